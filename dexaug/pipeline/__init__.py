"""The runs behind the commands: sim, augment and teleop wired into one job.

What it holds: the augmentation of one demo — :mod:`~dexaug.pipeline.run` (demo → validated
dataset + report; ``generate_grasps``, FSG wired to the validator),
:mod:`~dexaug.pipeline.options` (``AugmentOptions`` and the run key),
:mod:`~dexaug.pipeline.summary` (``summary.json``), :mod:`~dexaug.pipeline.report`,
:mod:`~dexaug.pipeline.result_lock`, :mod:`~dexaug.pipeline.exit_status`; demos —
:mod:`~dexaug.pipeline.demos` (a demo by name), :mod:`~dexaug.pipeline.demo_import` with
:mod:`~dexaug.pipeline.keyframe_files` (static keyframes → demos),
:mod:`~dexaug.pipeline.demo_chain`, :mod:`~dexaug.pipeline.scripted_demos`,
:mod:`~dexaug.pipeline.augment_queue`; arms — :mod:`~dexaug.pipeline.arm_run`,
:mod:`~dexaug.pipeline.arm_stage`, :mod:`~dexaug.pipeline.arm_report`,
:mod:`~dexaug.pipeline.rest_grasps`; and :mod:`~dexaug.pipeline.protocol_facts`, what commands
and reports ask of a validation protocol.

What to import: ``from dexaug.pipeline.run import augment_demo, generate_grasps`` for a run, the
others from their modules. Libraries here log, never print; the commands report.
"""
