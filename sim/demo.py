"""A grasp demonstration: the neutral record between the recorder and the augmenter.

Why it lives here, below both ``teleop`` and ``augment``: demos are made by extraction from a
recorded session (:mod:`teleop.record.demos`), by import of a static grasp pose, or from a
reference grasp, and consumed by AutoWS and FSG; neither side should import the other to
exchange one. The JSON form (:func:`save_demo`/:func:`load_demo`) is what ``recordings/demos/``
holds.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sim.errors import DexaugError
from sim.grasp import Grasp
from sim.io import write_bytes_atomic

__all__ = ["DEMO_FORMAT", "GRASP_TYPES", "POWER", "PRECISION", "Demo", "DemoError", "demo_from_json",
           "demo_to_json", "load_demo", "save_demo"]

DEMO_FORMAT = "dexaug-demo-1"
#: what kind of grasp a demo shows: ``precision`` (fingertips on the object, the paper's
#: demos, FSG augments them) or ``power`` (a whole-hand wrap: the palm or the inner phalanges
#: on the object too, which FSG's palm check refuses by design; :mod:`augment.power` augments
#: them). Older demo files, which carry no type, are precision demos.
PRECISION, POWER = "precision", "power"
GRASP_TYPES = (PRECISION, POWER)


class DemoError(DexaugError):
    """A session or file holds no usable grasp demonstration; the message says why."""


@dataclass(frozen=True, eq=False)
class Demo:
    """One grasp demonstration.

    Attributes:
        id: ``<session stem>@<seconds into the session>`` (provenance, cache keys).
        hand, object: hand config and object names.
        joints: (nq,) simulated joint angles at the grasp moment, radians, model order.
        palm_pos_m, palm_quat_wxyz: frame_palm in the object frame.
        tip_contacts: finger → (3,) mean contact point in that finger's tip body frame, metres
            (fingers that did not touch are absent).
        contact_points_obj: finger → (k,3) the contact points in the object frame, metres
            (a power demo's: of all the finger's links).
        source: the session file; time_s: seconds from the session start; how: "grasp_mark",
            "stable contact", "lift-confirmed contact" or "lift-confirmed wrap"; duration_s:
            length of the stable run (0 for a lone mark).
        table: the support the object rested on during the demonstration, when known: the
            plane in the object frame, ``{"point_m": (3,) a point on it, metres, "normal": (3,)
            its upward unit normal}``; None (the default, and older demo files) when unknown.
        flags: quality warnings extraction found (the object slipped in the hand, only a
            fragment of a larger grasp touched); empty when none. A flagged demo still
            augments: the flags tell the user to re-record it.
        grasp_type: :data:`PRECISION` (the default, and every older demo file) or
            :data:`POWER` (:data:`GRASP_TYPES`).
        link_contacts: the hand bodies other than fingertips (palm, phalanges) that touched
            the object at the grasp moment, sorted; empty when none did (or unknown).
    """

    id: str
    hand: str
    object: str
    joints: np.ndarray
    palm_pos_m: np.ndarray
    palm_quat_wxyz: np.ndarray
    tip_contacts: dict[str, np.ndarray]
    contact_points_obj: dict[str, np.ndarray]
    source: Path
    time_s: float
    how: str
    duration_s: float = 0.0
    fingers: tuple[str, ...] = field(default=())
    table: dict[str, np.ndarray] | None = None
    flags: tuple[str, ...] = field(default=())
    grasp_type: str = PRECISION
    link_contacts: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        if self.grasp_type not in GRASP_TYPES:
            raise DemoError(f"demo {self.id!r}: grasp_type must be one of {GRASP_TYPES}, got "
                            f"{self.grasp_type!r}")

    @property
    def grasp(self) -> Grasp:
        return Grasp.from_arrays(self.palm_pos_m, self.palm_quat_wxyz, self.joints)


def demo_to_json(demo: Demo) -> dict[str, Any]:
    """``demo`` as the plain data :func:`save_demo` writes (lists, numbers, strings). A
    precision demo without link contacts writes exactly what it did before those fields
    existed, so its file and the run key of its results (a hash of this) stay the same."""
    doc: dict[str, Any] = {
        "format": DEMO_FORMAT, "id": demo.id, "hand": demo.hand, "object": demo.object,
        "joints_rad": demo.joints.tolist(), "palm_pos_m": demo.palm_pos_m.tolist(),
        "palm_quat_wxyz": demo.palm_quat_wxyz.tolist(),
        "tip_contacts_m": {k: v.tolist() for k, v in demo.tip_contacts.items()},
        "contact_points_obj_m": {k: v.tolist() for k, v in demo.contact_points_obj.items()},
        "source": str(demo.source), "time_s": demo.time_s, "how": demo.how,
        "duration_s": demo.duration_s, "fingers": list(demo.fingers),
        "table": None if demo.table is None else {k: v.tolist() for k, v in demo.table.items()},
        "flags": list(demo.flags)}
    if demo.grasp_type != PRECISION:
        doc["grasp_type"] = demo.grasp_type
    if demo.link_contacts:
        doc["link_contacts"] = list(demo.link_contacts)
    return doc


def save_demo(path: Path | str, demo: Demo) -> None:
    """Write ``demo`` as JSON (atomically): small, diffable, committable."""
    write_bytes_atomic(path, (json.dumps(demo_to_json(demo), indent=1) + "\n").encode())


def load_demo(path: Path | str) -> Demo:
    """Read a demo written by :func:`save_demo`; errors name the file and the field."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise DemoError(f"{path}: not a readable demo file ({exc})") from None
    return demo_from_json(doc, path)


def demo_from_json(doc: Any, path: Path | str) -> Demo:
    """The demo in ``doc`` (:func:`demo_to_json`'s data, e.g. kept in a dataset's provenance);
    ``path`` names where it came from in errors (and is the source when ``doc`` has none)."""
    if not isinstance(doc, dict) or doc.get("format") != DEMO_FORMAT:
        raise DemoError(f"{path}: field 'format' must be {DEMO_FORMAT!r}")

    def arr(key: str, n: int | None, where: dict[str, Any] = doc, prefix: str = "") -> np.ndarray:
        try:
            a = np.asarray(where.get(key, []), float)
        except (TypeError, ValueError):   # strings, ragged lists: reported below
            a = np.empty((0, 0))
        if a.ndim != 1 or (n is not None and len(a) != n) or not np.isfinite(a).all():
            raise DemoError(f"{path}: field {prefix + key!r} must be {n or 'a list of'} finite "
                            f"numbers")
        return a

    def table() -> dict[str, np.ndarray] | None:
        plane = doc.get("table")
        if plane is None:
            return None
        if not isinstance(plane, dict) or set(plane) != {"point_m", "normal"}:
            raise DemoError(f"{path}: field 'table' must be null or {{\"point_m\": [x, y, z], "
                            f"\"normal\": [x, y, z]}} (the support plane in the object frame)")
        normal = arr("normal", 3, plane, "table.")
        if np.linalg.norm(normal) < 1e-9:
            raise DemoError(f"{path}: field 'table.normal' must be a non-zero 3-vector")
        return {"point_m": arr("point_m", 3, plane, "table."), "normal": normal / np.linalg.norm(normal)}

    if doc.get("grasp_type", PRECISION) not in GRASP_TYPES:
        raise DemoError(f"{path}: field 'grasp_type' must be one of {GRASP_TYPES} (absent: "
                        f"{PRECISION!r})")
    try:
        return Demo(id=str(doc["id"]), hand=str(doc["hand"]), object=str(doc["object"]),
                    joints=arr("joints_rad", None), palm_pos_m=arr("palm_pos_m", 3),
                    palm_quat_wxyz=arr("palm_quat_wxyz", 4),
                    tip_contacts={k: np.asarray(v, float)
                                  for k, v in doc.get("tip_contacts_m", {}).items()},
                    contact_points_obj={k: np.asarray(v, float).reshape(-1, 3)
                                        for k, v in doc.get("contact_points_obj_m", {}).items()},
                    source=Path(doc.get("source", path)), time_s=float(doc.get("time_s", 0.0)),
                    how=str(doc.get("how", "file")), duration_s=float(doc.get("duration_s", 0)),
                    fingers=tuple(doc.get("fingers", ())), table=table(),
                    flags=tuple(str(f) for f in doc.get("flags", ())),
                    grasp_type=str(doc.get("grasp_type", PRECISION)),
                    link_contacts=tuple(str(b) for b in doc.get("link_contacts", ())))
    except KeyError as exc:
        raise DemoError(f"{path}: missing field {exc}") from None
