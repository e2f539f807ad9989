"""Every scene the documentation shows works as written (issue 18).

Every ```toml block of docs/*.md and README.md is read as TOML and laid over the demo scene of its
kind (a block shows some tables whole; the demo supplies the others), and the result must load.  A block
that is a whole scene by itself is also swept, at H = 3 over its own range, and must complete.
"""
from __future__ import annotations

import copy
import re
import tomllib

import pytest

from jointfem.analysis.frf import compute_frf
from jointfem.app import check_forced_resonances, override_harmonics, sweep_options
from jointfem.scene import SceneError, create_structure, load_scene, parse_scene
from conftest import ROOT

BASE = {"lumped": "sdof_jenkins.toml", "beam2d": "beam2d.toml", "continuum3d": "lap3d.toml",
        "continuum2d": "lap2d.toml", "matrices": "matrices_xz.toml"}
DOCS = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]
BLOCKS = [(f"{doc.relative_to(ROOT)}#{i}", m.group(1))
          for doc in DOCS for i, m in enumerate(re.finditer(r"```toml\n(.*?)```", doc.read_text(), re.S))]


def test_the_docs_have_scene_blocks():
    assert len(BLOCKS) >= 5  # docs/scenes.md alone shows five


def _overlay(base: dict, block: dict) -> dict:
    """The base scene with each table the block shows replaced by the block's (a documented table
    is shown whole: merging it key by key could mix exclusive keys, as kt and kt_total)."""
    out = copy.deepcopy(base)
    out.update(copy.deepcopy(block))
    return out


@pytest.mark.parametrize("where,text", BLOCKS, ids=[b[0] for b in BLOCKS])
def test_every_documented_block_loads(where, text):
    block = tomllib.loads(text)
    kind = block.get("kind", "lumped")
    base = ROOT / "demos" / BASE[kind]
    parse_scene(_overlay(load_scene(base).data, block), base)  # file paths in it: relative to demos/


WHOLE = []
for where, text in BLOCKS:
    data = tomllib.loads(text)
    try:
        parse_scene(data, where)
    except SceneError:
        continue
    WHOLE.append((where, text))


def test_some_blocks_are_whole_scenes():
    assert {w for w, _ in WHOLE} >= {"docs/scenes.md#2", "docs/scenes.md#3"}
    # the continuum example is a whole scene too (issue 50, item 15: it had no [solver] and was refused)
    assert any(tomllib.loads(t)["kind"] == "continuum3d" and w.startswith("docs/scenes.md") for w, t in WHOLE)


@pytest.mark.parametrize("where,text", [w for w in WHOLE if tomllib.loads(w[1])["kind"] in ("lumped", "beam2d")],
                         ids=[w[0] for w in WHOLE if tomllib.loads(w[1])["kind"] in ("lumped", "beam2d")])
def test_every_whole_documented_scene_sweeps(where, text):
    """At H = 3 (N = 128) over the block's own range: the sweep completes and stays finite."""
    scene = override_harmonics(parse_scene(tomllib.loads(text), where), 3, 128)
    s = create_structure(scene)
    check_forced_resonances(scene, s)
    frf = compute_frf(s, sweep_options(scene, stability="off"))
    assert frf.info["status"] == "complete"
    assert frf.omega.max() >= scene.solver.omega_max - 1e-9 and frf.omega.min() <= scene.solver.omega_min + 1e-9


@pytest.mark.parametrize("demo", sorted(p.name for p in (ROOT / "demos").glob("*.toml")))
def test_every_demo_scene_loads(demo):
    load_scene(ROOT / "demos" / demo)
