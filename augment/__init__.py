"""The reference paper's augmenter: from one demonstration to many validated grasps.

What it holds: object clouds (:mod:`augment.object_cloud`), fingertip contact-face geometry
(:mod:`augment.geometry`), AutoWS workspace clouds (:mod:`augment.autows`), FSG sampling
(:mod:`augment.fsg`), power grasps (:mod:`augment.power`), the grasp dataset and its tables
(:mod:`augment.dataset`, :mod:`augment.grasp_table`) and exports to other tools' layouts
(:mod:`augment.export`). Pure NumPy/SciPy on arrays; MuJoCo only for the hand's kinematics.

What to import: ``from augment.autows.build import build_workspace``,
``from augment.fsg.run import generate``, ``from augment.object_cloud import object_cloud``,
``from augment import dataset`` (``dataset.load(path)``, ``dataset.save``) and
``from augment.export import write_fsg, write_bodex, …``. It imports ``sim`` only, never
``teleop`` or ``dexaug``; a validated run wired to MuJoCo is ``dexaug.pipeline.run``'s.
"""
