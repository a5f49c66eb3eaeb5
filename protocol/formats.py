"""The names of the serial IMU formats (``[imu] format``), importable without numpy (the command line's choices)."""

IMU_FORMATS = ("sinsalign", "stim300", "kvh1750", "kvh1775", "xsens", "frame")
GNSS_INPUTS = ("sinsalign", "nmea", "ubx")
"""The GNSS receiver outputs (``[aiding.gnss] input``): the project's aiding frames and messages, NMEA 0183, UBX."""
