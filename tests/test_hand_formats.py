"""Foreign formats' hand knowledge lives in the hand's folder (issue #51).

- every ``[formats.*]`` table of every hand resolves against that hand's model (its body and
  joints exist; the joints it drops are the exporter's to drop);
- a malformed table is refused on load in one line naming the file and the field;
- the exporters write the order the hand declares (a hand declaring another order gets that
  order in the file), and a hand that declares no such format is refused in one line that
  names its file and the hand that does declare it;
- the srh.txt importer takes its joint order and its hand from the declaration;
- the paper's hand is named in the paper config, checked on load.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest

from sim.errors import ConfigError, DexaugError
from sim.hand.config import HAND_FORMATS, hand_names, load_hand_config
from tests.conftest import needs_menagerie

if TYPE_CHECKING:
    from augment.grasp_table import ObjectTable
    from sim.hand.config import HandFormat
    from sim.hand.model import Hand

SHADOW = "shadow_right"
SHADOW_TOML = load_hand_config(SHADOW).file
KEYFRAMES = Path(__file__).resolve().parents[2] / "shared" / "assets" / "handdata" / \
    "fsg_keyframes"


def _shadow_with(**formats: HandFormat) -> Hand:
    """The Shadow Hand model under another name, with ``formats`` as its declarations."""
    from sim.hand.model import Hand

    cfg = load_hand_config(SHADOW)
    return Hand(dataclasses.replace(cfg, name="shadow_copy", formats=dict(formats)))


@needs_menagerie
@pytest.mark.parametrize("name", hand_names())
def test_every_declared_format_resolves_against_its_model(name: str) -> None:
    from augment.export.foreign import ForeignHand
    from sim.hand.model import Hand

    hand = Hand.load(name)
    for layout, fmt in hand.config.formats.items():
        assert set(fmt.joint_order) <= set(hand.joint_names), (name, layout)
        if layout in ("bodex", "fsg"):
            foreign = ForeignHand(hand, layout)
            assert foreign.joints == fmt.joint_order and foreign.body == fmt.body
            assert [hand.joint_names[i] for i in foreign.index] == list(fmt.joint_order)
        else:   # srh.txt places the palm body itself (dexaug.pipeline.demo_import)
            assert fmt.body == hand.config.palm.body


def test_the_shadow_declares_its_formats() -> None:
    cfg = load_hand_config(SHADOW)
    assert sorted(cfg.formats) == sorted(HAND_FORMATS)
    order = cfg.formats["fsg"].joint_order
    assert len(order) == 22 and order[0] == "rh_FFJ4" and order[-1] == "rh_THJ1"
    assert not any(j.startswith("rh_WRJ") for j in order)


_GOOD = SHADOW_TOML.read_text()


@pytest.mark.parametrize(("edit", "field", "message"), [
    (lambda s: s.replace("[formats.fsg]", "[formats.fgs]"), "formats", "unknown key(s) ['fgs']"),
    (lambda s: s.replace('joint_order = ["rh_FFJ4", "rh_FFJ3"', 'joint_order = ["rh_FFJ4", "rh_FFJ4"', 1),
     "formats.bodex.joint_order", "['rh_FFJ4'] more than once"),
    (lambda s: s.replace('body = "rh_palm"\njoint_order', 'joint_order', 1), "formats.bodex.body",
     "missing required key"),
    (lambda s: s.replace('joint_order = ["rh_FFJ4"', 'joint_order = [4, "rh_FFJ4"', 1),
     "formats.bodex.joint_order", "expected a list of strings"),
    (lambda s: s.replace('their_hand = "DexGraspBench', 'hand = "DexGraspBench', 1),
     "formats.bodex", "unknown key(s) ['hand']"),
])
def test_a_malformed_table_is_refused_in_one_line(tmp_path: Path, edit, field: str,
                                                  message: str) -> None:
    path = tmp_path / "shadow_bad" / "hand.toml"
    path.parent.mkdir()
    path.write_text(edit(_GOOD))
    assert path.read_text() != _GOOD
    with pytest.raises(ConfigError) as info:
        load_hand_config(path)
    text = str(info.value)
    assert text.startswith(f"{path}: {field}:") and message in text and "\n" not in text


def _table(hand: Hand, n: int = 3) -> ObjectTable:
    from augment.grasp_table import ObjectTable

    rng = np.random.default_rng(0)
    q = np.zeros((n, hand.nq))
    q[:, 2:] = rng.uniform(0.0, 0.3, (n, hand.nq - 2))   # fingers only: the wrist stays at 0
    quat = rng.normal(size=(n, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    return ObjectTable(columns={"palm_pose": np.c_[rng.normal(0, 0.05, (n, 3)), quat],
                                "hand_pose": q, "gws": rng.uniform(0, 0.05, n),
                                "pregrasp_pose": 0.5 * q, "squeeze_pose": 1.5 * q},
                       joint_names=tuple(hand.joint_names), finger_names=tuple(hand.finger_names))


@needs_menagerie
def test_the_exporters_write_the_order_the_hand_declares(tmp_path: Path) -> None:
    from augment.export import fsg_to_dexaug, read_bodex, read_fsg, write_bodex, write_fsg

    shadow = load_hand_config(SHADOW)
    turned = {k: dataclasses.replace(f, joint_order=f.joint_order[::-1])
              for k, f in shadow.formats.items()}
    hand = _shadow_with(**turned)
    table = _table(hand)
    q = table["hand_pose"]
    col = {j: i for i, j in enumerate(hand.joint_names)}
    want = q[:, [col[j] for j in turned["fsg"].joint_order]]
    write_fsg(tmp_path / "t.h5", {"062_dice": table}, hand)
    (group,) = read_fsg(tmp_path / "t.h5", hand).values()
    np.testing.assert_allclose(group.hand_pose, want, atol=1e-6)     # float32 in the file
    assert group.hand_pose[0, 0] == pytest.approx(q[0, col["rh_THJ1"]], abs=1e-6)
    _, back, _ = fsg_to_dexaug(group, hand)
    np.testing.assert_allclose(back, q, atol=1e-6)
    write_bodex(tmp_path / "b", {"062_dice": table}, hand)   # the table's own stages
    rec = read_bodex(tmp_path / "b", hand)[0]
    np.testing.assert_allclose(rec["grasp_qpos"][7:], want[0], atol=1e-12)
    np.testing.assert_allclose(rec["squeeze_qpos"][7:], 1.5 * want[0], atol=1e-12)


@needs_menagerie
def test_a_hand_without_the_format_is_refused_in_one_line(tmp_path: Path) -> None:
    from augment.export import write_bodex, write_fsg
    from sim.hand.model import Hand

    bare = _shadow_with()   # the Shadow's joints, but no declaration: not guessed
    with pytest.raises(DexaugError) as info:
        write_fsg(tmp_path / "x.h5", {}, bare)
    text = str(info.value)
    assert text.startswith("hand 'shadow_copy' cannot be written in the fsg layout: ")
    assert f"{SHADOW_TOML} declares no [formats.fsg]; shadow_right declares it" in text
    assert "copy that table" in text and "\n" not in text
    with pytest.raises(DexaugError, match=r"hand 'leap_right' cannot be written in the bodex "
                                          r"layout: .*leap_right/hand.toml declares no "
                                          r"\[formats.bodex\].*lacks rh_FFJ4, rh_FFJ3, rh_FFJ2, "
                                          r"rh_FFJ1 and 18 more$"):
        write_bodex(tmp_path / "b", {}, Hand.load("leap_right"))
    assert not (tmp_path / "x.h5").exists() and not (tmp_path / "b").exists()


@needs_menagerie
@pytest.mark.skipif(not (KEYFRAMES / "srh.txt").is_file(), reason="no fsg_keyframes in ../shared")
def test_srh_txt_takes_the_declared_order_and_hand() -> None:
    from dexaug.pipeline.demo_import import _declaring_hand
    from dexaug.pipeline.keyframe_files import joint_vector, read_keyframes
    from sim.hand.model import Hand

    kf = read_keyframes(KEYFRAMES / "srh.txt")[0]
    assert _declaring_hand(kf) == SHADOW
    shadow = Hand.load(SHADOW)
    q, left_out = joint_vector(kf, shadow)
    assert left_out == ["rh_WRJ2", "rh_WRJ1"]
    order = shadow.config.formats["srh_txt"].joint_order
    turned = _shadow_with(srh_txt=dataclasses.replace(shadow.config.formats["srh_txt"],
                                                      joint_order=order[::-1]))
    q_turned, _ = joint_vector(kf, turned)
    col = {j: i for i, j in enumerate(shadow.joint_names)}
    assert q_turned[col[order[-1]]] == q[col[order[0]]] and not np.allclose(q_turned, q)
    with pytest.raises(ConfigError, match=r"hand 'allegro_right' cannot take the srh.txt "
                                          r"keyframe .*srh.txt:1: .* declares no "
                                          r"\[formats.srh_txt\]; shadow_right declares it"):
        joint_vector(kf, Hand.load("allegro_right"))


def test_the_paper_names_its_hand(tmp_path: Path) -> None:
    from dexaug.bench_paper import PAPER_TABLES, paper_figures, paper_hand

    assert paper_hand() == SHADOW
    text = PAPER_TABLES.read_text()
    bad = tmp_path / "paper.toml"
    bad.write_text(text.replace(f'hand = "{SHADOW}"', 'hand = "shadow_rigth"'))
    with pytest.raises(ConfigError, match=rf"^{bad}: hand: no hand folder .*shadow_rigth"):
        paper_hand(bad)
    bad.write_text(text.replace(f'hand = "{SHADOW}"', ""))
    with pytest.raises(ConfigError, match=rf"^{bad}: hand: missing required key$"):
        paper_hand(bad)
    bad.write_text(text.replace("values = {", "valeus = {", 1))
    with pytest.raises(ConfigError, match=r"rows\[0\]: unknown key\(s\) \['valeus'\]"):
        paper_figures(bad)
