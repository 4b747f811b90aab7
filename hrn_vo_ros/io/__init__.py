"""I/O layer: message conversion, dataset readers, bag writing and reading.

``hrn_vo_ros/io/msg/<package>/*.msg`` are the interface definitions this project needs that PyPI
lacks; they match the official packages field for field (and so their RIHS01 type hashes).
"""
