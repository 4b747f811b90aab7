"""The pure core: all of the math, numpy/scipy and the standard library only.

Split by concern (``docs/architecture.md`` has the module table):

* :mod:`.events`: event arrays, sequences (calibration, IMU, trajectories), the lens model and
  the event-frame packetizer;
* :mod:`.hrn`: the hierarchical resonator network (FHRR codebooks, log-polar transform, FFTs,
  sphere correction, configs, engines, the network) and the backend registry;
* :mod:`.spiking`: the spiking phasor backend under Loihi constraints;
* :mod:`.odometry`: estimates, rotations, gyro integration, readout to REP-103 poses;
* :mod:`.sim`: the event-camera simulator;
* :mod:`.evaluation`: the paper's evaluation protocol and the classical baseline;
* :mod:`.configbase`: the frozen-dataclass machinery every stage's config is built with.

No module below this package may import rclpy, rosbags or ROS message packages
(``test/test_layering.py`` enforces it).
"""
