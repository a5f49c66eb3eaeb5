"""The names of the serial IMU formats (``[imu] format``), importable without numpy (the command line's choices)."""

IMU_FORMATS = ("sinsalign", "stim300", "kvh1750", "kvh1775", "xsens", "frame")
