"""Subcommand ``ui``: the local dashboard (``dexaug.dashboard``).

The augmentation options are the ``augment`` command's own (same flags, same meaning and
defaults), so a demo augmented from the page and one augmented with ``dexaug augment`` under the
same options share their results. The page listens on :data:`DASHBOARD_PORT`, not on Foxglove's
8765 (``dexaug bridge --foxglove``), so both run at once.
"""

from __future__ import annotations

import argparse
import logging
import threading
from pathlib import Path

from rich.console import Console
from rich.text import Text

from dexaug.commands.argtypes import free_port, int_at_least
from dexaug.commands.guards import require_writable
from dexaug.commands.options import augment_options, generation_args
from dexaug.commands.registry import command
from dexaug.commands.workers import stop_workers

log = logging.getLogger(__name__)

#: the dashboard's default port (dexaug.dashboard.server.DashboardConfig's): beside Foxglove's
#: 8765 (dexaug.commands.teleop.FOXGLOVE_PORT), which ``bridge --foxglove`` listens on
DASHBOARD_PORT = 8770


def _ui_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--sessions", type=Path, default=Path("recordings"), metavar="DIR",
                   help="folder of recorded sessions (*.mcap; default ./recordings)")
    p.add_argument("--out", type=Path, default=Path("datasets"),
                   help="output folder: one sub-folder per demo (default ./datasets)")
    p.add_argument("--host", default="127.0.0.1", help="listen address (default 127.0.0.1: "
                   "this machine only)")
    p.add_argument("--port", type=free_port, default=DASHBOARD_PORT,
                   help="listen port (0: any free port); default %(default)s, beside the Foxglove "
                   "live view's 8765 (bridge --foxglove)")
    p.add_argument("--gallery", type=int_at_least(0), default=6,
                   help="grasps rendered in each report (0: no report)")
    generation_args(p)


@command("ui", _ui_args)
def ui_cmd(args: argparse.Namespace, console: Console) -> int:
    """Serve the dashboard: sessions, their demos, one-click augmentation with live progress.

    Lists every session of --sessions with its demos (thumbnail, object, fingers, time) or the
    reason it has none; "Augment" runs demo → AutoWS → FSG → validation → dataset + report in
    the background (one at a time), shows the progress, then the numbers and the report.
    Demos already augmented with the same inputs show their results directly. Ctrl-C stops.
    """
    from dexaug.dashboard.server import Dashboard, DashboardConfig

    require_writable(args.out, "--out", folder=True)
    cfg = DashboardConfig(sessions_dir=args.sessions, out_root=args.out,
                          options=augment_options(args), host=args.host, port=args.port)
    with Dashboard(cfg) as dash:
        url = dash.start()
        console.print(Text.assemble("dashboard on ", (url, "bold"), " (Ctrl-C to stop)"))
        try:
            threading.Event().wait()
        except KeyboardInterrupt:
            console.print("stopping")
            stop_workers()   # a job under way: its FSG workers would run to the budget
    return 0
