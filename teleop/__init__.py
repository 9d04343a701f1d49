"""Teleoperation: hand-tracking messages, ingest, the zenoh bridge, mink retargeting, MCAP
recording and replay."""
