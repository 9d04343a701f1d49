"""Exit statuses of the ``dexaug`` commands, shared by the CLI that returns them and the code
that runs those commands as child processes and must read them (the bridge's
``--auto-augment`` queue, :mod:`dexaug.pipeline.augment_queue`).

0: done; 1: failed; 2: usage or input error; :data:`SHORT_STATUS`: results written, but fewer
than :data:`SHORT_SHARE` of the grasps asked for (e.g. stopped by ``--budget``) — not a failure
of the run, a request that could not be met.
"""

from __future__ import annotations

__all__ = ["SHORT_SHARE", "SHORT_STATUS"]

#: a run that returns fewer than this share of ``--n`` grasps exits with :data:`SHORT_STATUS`
#: after writing what it made: a shortfall of a few grasps is normal for a hard object, one of
#: more than half means the request could not be met
SHORT_SHARE = 0.5
#: the exit status of a run that fell short
SHORT_STATUS = 3
