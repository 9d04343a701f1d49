"""``dexaug ui``: a local web page listing recorded sessions and their grasp demos, with a
one-click augmentation per demo (live progress, then the report and its numbers), and its
grasps put on an arm at a table.

:mod:`~dexaug.dashboard.catalog` lists sessions, demos, thumbnails and finished results;
:mod:`~dexaug.dashboard.jobs` runs one job at a time on a worker thread (a bounded list);
:mod:`~dexaug.dashboard.arm_jobs` puts a finished result's grasps on an arm (a job of that queue);
:mod:`~dexaug.dashboard.guard` refuses foreign Hosts, cross-site requests and, beyond loopback,
requests without the per-start token;
:mod:`~dexaug.dashboard.server` serves the page (``static/``) and its JSON API.
"""
