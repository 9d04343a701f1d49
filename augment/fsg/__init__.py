"""augment.fsg: fingertip-contact-aware sampling-based grasp generation (paper section 4;
DESIGN §4).

Inputs are an :class:`~augment.object_cloud.ObjectCloud` (``cloud_full`` and ``cloud_part``,
object frame) and an AutoWS :class:`~augment.autows.cloud.WorkspaceCloud` (per finger,
fingertip contact-face centres in ``frame_palm`` with the joint angles that put them there). No
inverse kinematics is ever computed and, up to the last check of step 6, no mesh collision:
everything is point-cloud arithmetic, vectorised over batches of palm pose candidates. The
entry point is :func:`augment.fsg.run.generate`; parameters are in :mod:`augment.fsg.params`,
the returned types in :mod:`augment.fsg.result`, and one batch is strung together by
:class:`augment.fsg.batch.Sampler`. Each step's module holds its details:

1. **Palm pose candidates** (:mod:`augment.fsg.candidates`): a random point of ``cloud_part``
   and a random point of the smallest active workspace cloud (on its contact face), aligned
   (positions coincide, normals opposed), then rotated about that normal by ``2πi/inner`` →
   ``outer_batch × inner`` rigid transforms object → palm.
2. **Palm checks** (:mod:`augment.fsg.candidates`): more than ``max_palm_points`` object points in
   the palm box, or (table mode) palm box vertices or contact-face rims within
   ``table_clearance_m`` of the table plane through the object's lowest point.
3. **Other fingers** (:mod:`augment.fsg.matching`): in priority order, a 6-D k-d tree match of the
   transformed ``cloud_part`` with each finger's workspace cloud (distance < 8 mm, opposed
   normals), minus the points the paper's eq. 2 removes around earlier contacts; one usable
   pair drawn per candidate.
4. **Finger crossing** (:mod:`augment.fsg.matching`): within each opposition group, contacts keep
   the order of their clouds along the group's spread axis.
5. **Contacts** (:mod:`augment.fsg.contacts`): the ``cloud_full`` points on each rebuilt contact
   face (within 5 mm of its plane, facing it); ≥ 1 per finger, ≥ ``min_contacts`` in all; a
   fingertip buried in the object is rejected.
6. **Link penetration** (:mod:`augment.fsg.checks`, optional): paper eq. 3 and a clearance on the
   link skeletons, then the caller's exact check in the validator's MuJoCo scene.
7. **Quality** (:mod:`augment.fsg.checks`): GWS Q1 (ε) and volume; ε ≤ ``min_epsilon`` is dropped
   unless a short round relaxed the filter (:mod:`augment.fsg.run`).
8. **De-duplication** (:mod:`augment.fsg.checks`): against the accepted grasps (5 mm, |q·q'| >
   1 − 5e-3, every joint within 0.1 rad).

Finger iteration and parallel workers (:mod:`augment.fsg.run`): fingers are dropped, least
important first, when a round yields fewer than ``min_valid`` grasps; worker k is seeded
``seed + k`` and the workers' grasps are merged and de-duplicated again, so a seed and worker
count give the same grasps.
"""
