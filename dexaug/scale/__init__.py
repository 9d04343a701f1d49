"""Scale-out of the augmentation over many demos and objects (``dexaug batch``, ``--ray``).

:mod:`dexaug.scale.units` turns inputs into units of work (a demo, or an object on the hand's
manual workspace) and runs one in this process; :mod:`dexaug.scale.ray_cluster` connects to a Ray
cluster or starts one bound to loopback; :mod:`dexaug.scale.ray_jobs` runs units as Ray tasks
(FSG per unit, validation in chunks) while the driver alone writes every result folder. Ray is
an optional dependency (``pip install 'dexaug[ray]'``); nothing here imports it until asked.
"""
