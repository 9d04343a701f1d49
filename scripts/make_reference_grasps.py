"""Rebuild the default hand's ``configs/hands/<hand>/grasps.toml``: hand-built grasps on YCB objects.

The placements below were chosen for the Shadow Hand (the default hand).

Each grasp is made the way a person would: put the palm against the object, close the fingers
until they stop (sim.world.closing), and store what the hand ended up with. Run:
``.venv/bin/python scripts/make_reference_grasps.py``.
"""

from __future__ import annotations

import numpy as np

from sim.hand.config import default_hand_name, hand_dir
from sim.hand.model import Hand
from sim.io import write_bytes_atomic
from sim.transforms import mat_to_quat
from sim.world.closing import close_on_object
from sim.world.objects import load_object
from sim.world.scene import Scene

# (name, object, palm position in the object frame (m), frame_palm's x, y, z axes expressed in
#  the object frame, note). The placements were chosen by trying palm sides, finger directions
#  and heights around each object and keeping ones that hold under both protocols.
SPECS = [
    ("can_side_wrap", "005_tomato_soup_can", [0.001, 0.046, 0.109],
     [[1, 0, 0], [0, -1, 0], [0, 0, -1]],
     "palm on the can's +y side near the top, fingers pointing down and wrapping around it"),
    ("box_edge_wrap", "004_sugar_box", [-0.027, -0.076, 0.168],
     [[-1, 0, 0], [0, 1, 0], [0, 0, -1]],
     "palm on the box's narrow -y face near the top, fingers pointing down and around the edges"),
    ("bowl_side_grasp", "024_bowl", [-0.095, 0.049, 0.047],
     [[0, 0, 1], [0, -1, 0], [1, 0, 0]],
     "palm against the bowl's outer wall on +y, fingers pointing +x along the wall"),
]


def main() -> None:
    hand = Hand.load(default_hand_name())
    lines = ["# Hand-built reference grasps of the Shadow Hand (ground truth for the validator).",
             "# Made by scripts/make_reference_grasps.py: palm placed by hand, fingers closed",
             "# in MuJoCo until they stop on the held-still object. Radians and metres; palm pose",
             "# = frame_palm in the object frame, quaternion w, x, y, z.", ""]
    for name, obj_name, pos, axes, note in SPECS:
        scene = Scene(hand, load_object(obj_name))
        quat = mat_to_quat(np.array(axes, float).T)
        grasp = close_on_object(scene, np.array(pos, float), quat, hand.posture("preshape_pose"),
                                hand.posture("close_pose"))
        joints = ", ".join(f"{n} = {v:.4f}" for n, v in zip(hand.joint_names, grasp.joints,
                                                           strict=True))
        lines += ["[[grasps]]", f'name = "{name}"', f'object = "{obj_name}"', f'note = "{note}"',
                  f"palm_pos = [{', '.join(f'{v:.5f}' for v in grasp.palm_pos)}]",
                  f"palm_quat_wxyz = [{', '.join(f'{v:.6f}' for v in grasp.palm_quat_wxyz)}]",
                  f"joints = {{ {joints} }}", ""]
    write_bytes_atomic(hand_dir(hand.name) / "grasps.toml", "\n".join(lines).encode())


if __name__ == "__main__":
    main()
