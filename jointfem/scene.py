"""Scene files (TOML) -> validated, frozen specifications.  Nothing is computed here.

Every error names the file, the key and the bad value, in one line:

    beam.toml: [joint].mu = -0.1: must be >= 0

See docs/scenes.md for the keys of each kind.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .models.beam2d import Beam2DSpec
from .models.beam2d import dof_names as beam_dof_names
from .models.beam2d import resolve_dof
from .models.lumped import AXES, GROUND, ForceSpec, JenkinsSpec, LinkSpec, LumpedSpec, MassSpec
from .models.lumped import dof_names as lumped_dof_names

KINDS = ("lumped", "beam2d")


class SceneError(ValueError):
    """Bad scene input: names the file, the key and the value."""

    def __init__(self, path, key: str, value: Any, message: str):
        self.path, self.key, self.value = str(path), key, value
        super().__init__(f"{path}: {key} = {value!r}: {message}")


@dataclass(frozen=True)
class SolverSpec:
    omega_min: float  # rad/s
    omega_max: float  # rad/s
    direction: str = "up"  # sweep from omega_min up, or from omega_max down
    harmonics: int = 5
    samples: int = 256
    ds0: float = 0.02
    ds_min: float = 1e-6
    ds_max: float = 0.1
    tol: float = 1e-10
    max_points: int = 5000

    @property
    def omega_start(self) -> float:
        return self.omega_min if self.direction == "up" else self.omega_max

    @property
    def omega_end(self) -> float:
        return self.omega_max if self.direction == "up" else self.omega_min


@dataclass(frozen=True)
class Scene:
    path: Path
    kind: str
    name: str
    solver: SolverSpec
    model: Any  # LumpedSpec | Beam2DSpec
    data: dict  # the parsed TOML, for the record


_REQUIRED = object()


class _Table:
    """Reads one TOML table, checking types and values, and then that no key is left over."""

    def __init__(self, path, data, where: str):
        self.path, self.where = path, where
        if not isinstance(data, dict):
            raise SceneError(path, where or "(top level)", data, "must be a table")
        self.data = data
        self.used: set[str] = set()

    def key(self, k: str) -> str:
        return f"{self.where}.{k}" if self.where else k

    def fail(self, k: str, v, msg: str):
        raise SceneError(self.path, self.key(k), v, msg)

    def has(self, k: str) -> bool:
        return k in self.data

    def raw(self, k: str, default=_REQUIRED):
        self.used.add(k)
        if k not in self.data:
            if default is _REQUIRED:
                raise SceneError(self.path, self.key(k), None, "required key is missing")
            return default
        return self.data[k]

    def number(self, k: str, default=_REQUIRED, *, gt=None, ge=None) -> float:
        v = self.raw(k, default)
        if v is default and default is not _REQUIRED:
            return v
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(k, v, "must be a number")
        if not math.isfinite(v):
            self.fail(k, v, "must be finite")
        if gt is not None and not v > gt:
            self.fail(k, v, f"must be > {gt}")
        if ge is not None and not v >= ge:
            self.fail(k, v, f"must be >= {ge}")
        return float(v)

    def integer(self, k: str, default=_REQUIRED, *, ge=None) -> int:
        v = self.raw(k, default)
        if v is default and default is not _REQUIRED:
            return v
        if isinstance(v, bool) or not isinstance(v, int):
            self.fail(k, v, "must be an integer")
        if ge is not None and v < ge:
            self.fail(k, v, f"must be >= {ge}")
        return int(v)

    def string(self, k: str, default=_REQUIRED, *, choices=None) -> str:
        v = self.raw(k, default)
        if v is default and default is not _REQUIRED:
            return v
        if not isinstance(v, str):
            self.fail(k, v, "must be a string")
        if choices is not None and v not in choices:
            self.fail(k, v, f"must be one of {', '.join(choices)}")
        return v

    def strings(self, k: str, default=_REQUIRED, *, min_len=1, max_len=None) -> tuple[str, ...]:
        v = self.raw(k, default)
        if v is default and default is not _REQUIRED:
            return v
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
            self.fail(k, v, "must be a list of strings")
        if len(v) < min_len or (max_len is not None and len(v) > max_len):
            self.fail(k, v, f"must have {min_len}" + (f" to {max_len}" if max_len else " or more") + " entries")
        return tuple(v)

    def table(self, k: str, *, required=True) -> "_Table":
        v = self.raw(k, _REQUIRED if required else {})
        return _Table(self.path, v, self.key(k))

    def tables(self, k: str, *, required=True) -> list["_Table"]:
        v = self.raw(k, _REQUIRED if required else [])
        if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
            self.fail(k, v, "must be an array of tables ([[...]])")
        if required and not v:
            self.fail(k, v, "must have at least one entry")
        return [_Table(self.path, x, f"{self.key(k)}[{i}]") for i, x in enumerate(v)]

    def done(self):
        extra = sorted(set(self.data) - self.used)
        if extra:
            k = extra[0]
            raise SceneError(self.path, self.key(k), self.data[k], "unknown key")


def _solver(t: _Table) -> SolverSpec:
    rng = t.raw("omega_range")
    if (not isinstance(rng, list) or len(rng) != 2
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in rng)):
        t.fail("omega_range", rng, "must be [omega_min, omega_max] in rad/s")
    lo, hi = float(rng[0]), float(rng[1])
    if lo <= 0:
        t.fail("omega_range", rng, "omega_min must be > 0 rad/s")
    if hi == lo:
        t.fail("omega_range", rng, "empty frequency range (omega_min == omega_max)")
    if hi < lo:
        t.fail("omega_range", rng, "reversed frequency range (omega_min > omega_max); use direction = \"down\" "
                                   "to sweep downwards")
    H = t.integer("harmonics", 5, ge=1)
    N = t.integer("samples", max(256, 4 * H + 4))
    if N < 2 * H + 1:
        t.fail("samples", N, f"must be >= 2*harmonics+1 = {2 * H + 1}")
    spec = SolverSpec(
        omega_min=lo, omega_max=hi, direction=t.string("direction", "up", choices=("up", "down")),
        harmonics=H, samples=N, ds0=t.number("ds0", 0.02, gt=0), ds_min=t.number("ds_min", 1e-6, gt=0),
        ds_max=t.number("ds_max", 0.1, gt=0), tol=t.number("tol", 1e-10, gt=0),
        max_points=t.integer("max_points", 5000, ge=2))
    if not spec.ds_min <= spec.ds0 <= spec.ds_max:
        t.fail("ds0", spec.ds0, f"must lie in [ds_min, ds_max] = [{spec.ds_min}, {spec.ds_max}]")
    t.done()
    return spec


def _check_dofs(t: _Table, key: str, names, known, resolve=lambda s: s):
    for nm in names:
        if resolve(nm) not in known:
            sample = ", ".join(list(known)[:6])
            t.fail(key, nm, f"no such DOF (known: {sample}{', ...' if len(known) > 6 else ''})")


def _lumped(top: _Table) -> LumpedSpec:
    masses = []
    for t in top.tables("mass"):
        name = t.string("name")
        if name == GROUND or "." in name or not name:
            t.fail("name", name, "must be a non-empty name without '.' and not 'ground'")
        if any(m.name == name for m in masses):
            t.fail("name", name, "duplicate mass name")
        dofs = t.strings("dofs", ("x",), min_len=1, max_len=3)
        for d in dofs:
            if d not in AXES:
                t.fail("dofs", d, "must be x, y or z")
        if len(set(dofs)) != len(dofs):
            t.fail("dofs", list(dofs), "repeated axis")
        masses.append(MassSpec(name, t.number("m", gt=0), dofs))
        t.done()
    known = set(lumped_dof_names(LumpedSpec(tuple(masses))))
    nodes = {m.name: set(m.dofs) for m in masses}

    def links(key, value_key, ge_or_gt):
        out = []
        for t in top.tables(key, required=False):
            ab = t.strings("between", min_len=2, max_len=2)
            if ab[0] == GROUND:
                t.fail("between", list(ab), "the first entry must be a DOF (ground goes second)")
            _check_dofs(t, "between", [x for x in ab if x != GROUND], known)
            if ab[0] == ab[1]:
                t.fail("between", list(ab), "a link needs two different DOFs")
            v = t.number(value_key, **ge_or_gt)
            out.append(LinkSpec(ab[0], ab[1], v))
            t.done()
        return tuple(out)

    springs = links("spring", "k", {"gt": 0})
    dampers = links("damper", "c", {"ge": 0})
    jenkins = []
    for t in top.tables("jenkins", required=False):
        ab = t.strings("between", min_len=2, max_len=2)
        for i, nd in enumerate(ab):
            if nd not in nodes and not (nd == GROUND and i == 1):
                t.fail("between", nd, "no such mass" + (" (ground goes second)" if nd == GROUND else ""))
        tang = t.strings("tangential", min_len=1, max_len=2)
        normal = t.string("normal", None)
        axes = list(tang) + ([normal] if normal is not None else [])
        if len(set(axes)) != len(axes):
            t.fail("tangential", list(tang), "tangential and normal axes must differ")
        for nd in ab:
            if nd == GROUND:
                continue
            for ax in axes:
                if ax not in nodes[nd]:
                    t.fail("normal" if ax == normal else "tangential", ax, f"mass {nd!r} has no DOF {ax!r}")
        kt = t.number("kt", gt=0)
        kn = t.number("kn", gt=0) if normal is not None else t.number("kn", 0.0, ge=0)
        jenkins.append(JenkinsSpec(ab[0], ab[1], tang, normal, kt, kn, t.number("mu", ge=0), t.number("N0", ge=0)))
        t.done()
    forces = []
    for t in top.tables("force"):
        dof = t.string("dof")
        _check_dofs(t, "dof", [dof], known)
        forces.append(ForceSpec(dof, t.number("amplitude"), t.number("phase", 0.0)))
        t.done()
    out = top.table("output")
    outputs = out.strings("dofs")
    _check_dofs(out, "dofs", outputs, known)
    out.done()
    return LumpedSpec(tuple(masses), springs, dampers, tuple(jenkins), tuple(forces), outputs)


def _beam2d(top: _Table) -> Beam2DSpec:
    d = Beam2DSpec()
    b = top.table("beam", required=False)
    elements = b.integer("elements", d.elements, ge=2)
    if elements % 2:
        b.fail("elements", elements, "must be even (the force acts at the middle node of beam 1)")
    geo = dict(length=b.number("length", d.length, gt=0), width=b.number("width", d.width, gt=0),
               height=b.number("height", d.height, gt=0), density=b.number("density", d.density, gt=0),
               young=b.number("young", d.young, gt=0), elements=elements)
    b.done()
    j = top.table("joint", required=False)
    num_pairs = j.integer("pairs", d.num_pairs, ge=1)
    if num_pairs > elements:
        j.fail("pairs", num_pairs, f"must be <= beam.elements = {elements}")
    joint = dict(num_pairs=num_pairs, kt=j.number("kt", d.kt, gt=0), kn=j.number("kn", d.kn, gt=0),
                 kr=j.number("kr", d.kr, gt=0), mu=j.number("mu", d.mu, ge=0), N0=j.number("N0", d.N0, ge=0))
    j.done()
    dm = top.table("damping", required=False)
    kind = dm.string("kind", "modal", choices=("modal", "rayleigh"))
    if kind == "modal":
        damp = dict(damping="modal", modal_ratio=dm.number("ratio", d.modal_ratio, ge=0))
    else:
        damp = dict(damping="rayleigh", rayleigh_alpha=dm.number("alpha", 0.0, ge=0),
                    rayleigh_beta=dm.number("beta", 0.0, ge=0))
    dm.done()
    f = top.table("force", required=False)
    force = f.number("amplitude", d.force)
    f.done()
    spec = Beam2DSpec(**geo, **joint, **damp, force=force)
    out = top.table("output", required=False)
    outputs = out.strings("dofs", d.outputs)
    _check_dofs(out, "dofs", outputs, set(beam_dof_names(spec)), lambda s: resolve_dof(spec, s))
    out.done()
    return Beam2DSpec(**geo, **joint, **damp, force=force, outputs=outputs)


def load_scene(path) -> Scene:
    """Read and validate a scene file.  Raises SceneError (one line) on any bad input."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise SceneError(path, "(file)", str(path), f"cannot be read: {exc.strerror or exc}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(path, "(syntax)", None, f"not valid TOML: {exc}") from None
    return parse_scene(data, path)


def parse_scene(data: dict, path="<scene>") -> Scene:
    top = _Table(path, data, "")
    kind = top.string("kind", choices=KINDS)
    name = top.string("name", Path(str(path)).stem)
    solver = _solver(top.table("solver"))
    model = _lumped(top) if kind == "lumped" else _beam2d(top)
    top.done()
    return Scene(Path(str(path)), kind, name, solver, model, data)


def create_structure(scene: Scene):
    """Build the physical model of a scene (only the kind it needs is imported)."""
    if scene.kind == "lumped":
        from .models.lumped import create_lumped
        return create_lumped(scene.model)
    from .models.beam2d import create_beam2d
    return create_beam2d(scene.model)
