"""Recorded teleop sessions: the MCAP recorder (``recorder.py``, atomic, readable when cut
short), reading and repairing sessions (``session.py``, ``session_file.py``, ``repair.py``),
their replay through the bridge (``replay.py``), and the demonstrations extracted from them
(``demos.py``, ``demo_track.py``: the thumb and another fingertip on the object;
``power_demo.py``: a whole-hand wrap).
"""
