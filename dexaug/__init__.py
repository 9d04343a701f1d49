"""The product: the ``dexaug`` command line, the pipeline it runs, the dashboard and the viewer.

What it holds: :mod:`dexaug.cli` (``main``; ``dexaug --help``) and its subcommands
(:mod:`dexaug.commands`), the runs that wire ``sim``, ``augment`` and ``teleop`` together
(:mod:`dexaug.pipeline`: one demo → a validated dataset and report), scale-out over many
demos (:mod:`dexaug.scale`), the local web dashboard (:mod:`dexaug.dashboard`), the 3D grasp
viewer (:mod:`dexaug.viewer`) and the paper benchmark (:mod:`dexaug.bench_paper`).

What to import: to run a command from code, ``from dexaug.cli import main``
(``main(["generate", "--object", "062_dice"])``); to run the augmentation of a demo,
:func:`dexaug.pipeline.run.augment_demo`'s module. ``dexaug`` is the top layer: it may import
every package; no other package imports it.
"""
