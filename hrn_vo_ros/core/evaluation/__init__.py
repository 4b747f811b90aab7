"""The paper's evaluation protocol and the classical baseline it is compared with."""
