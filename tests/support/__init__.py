"""Helpers shared by the test folders (imported as ``support.…``: pytest puts tests/ on the path, pyproject.toml).

``daemon_harness``: a daemon on free loopback ports with a subscriber, simulated IMU samples, the offline-replay
comparison and ``wait_until``. ``aided_runs``: a simulated seed through an aided pipeline and its errors.
``config_keys``: one key of a (sub-)table as a mapping.
"""
