"""A run folder and the trials in it: one owner of its layout.

``runner`` turns a scenario into trial specs (paired seeds) and their components; ``folder`` makes,
locks and resumes a run folder; ``files`` names what it holds and is the one way a file of it is
opened; ``trial_files`` and ``artefacts`` write what a trial leaves as it ends (its picture with a
``captions`` line, ROS 2 bag, ``rerun_recording``); ``live_trial`` is a run folder of one trial recorded as
it happens (serve-robot's and guard-mcp's sessions).
"""
