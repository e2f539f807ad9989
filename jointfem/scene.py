"""Scene files (TOML) -> validated, frozen specifications.  Nothing is computed here.

Every error names the file, the key and the bad value, in one line:

    beam.toml: [joint].mu = -0.1: must be >= 0

See docs/scenes.md for the keys of each kind.
"""
from __future__ import annotations

import logging
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .continuation.arclength import ContinuationOptions, NewtonOptions
from .defaults import ROM_MODES, ROM_TVD, default_samples
from .models.beam2d import Beam2DSpec
from .models.beam2d import dof_names as beam_dof_names
from .models.beam2d import resolve_dof
from .models.lumped import AXES, GROUND, ForceSpec, GapSpringSpec, JenkinsSpec, LinkSpec, LumpedSpec, MassSpec
from .models.lumped import dof_names as lumped_dof_names

KINDS = ("lumped", "beam2d", "continuum2d", "continuum3d", "matrices")
AFT_KINDS = ("sampled", "events")


MISSING = type("Missing", (), {"__repr__": lambda self: "MISSING"})()  # the value of a key the input lacks


class SceneError(ValueError):
    """Bad scene input: names the file, the key and the value (MISSING: the key is not there)."""

    def __init__(self, path, key: str, value: Any, message: str):
        self.path, self.key, self.value = str(path), key, value
        super().__init__(f"{path}: {key}: {message}" if value is MISSING else f"{path}: {key} = {value!r}: {message}")


@dataclass(frozen=True)
class SolverSpec:
    omega_min: float  # rad/s
    omega_max: float  # rad/s
    direction: str = "up"  # sweep from omega_min up, or from omega_max down
    harmonics: int = 5
    samples: int = default_samples(5)
    # harmonics = "auto": H grows from `harmonics` by 2 until every point's truncation estimate
    # (analysis.convergence) is at most harmonic_target, up to harmonics_max; samples then follow
    # defaults.default_samples(H) unless the scene gives them
    harmonics_auto: bool = False
    harmonic_target: float = 0.05
    harmonics_max: int = 25
    # harmonics = "auto": how far, over the branch's largest amplitude so far, a point solved at H + 2
    # may lie from the branch at H (analysis.adaptive.branch_distance)
    amplitude_tol: float = 5e-3
    samples_given: bool = True
    # the continuation's own defaults (defined once, in jointfem.continuation.arclength)
    ds0: float = ContinuationOptions.ds0
    ds_min: float = ContinuationOptions.ds_min
    ds_max: float = ContinuationOptions.ds_max
    tol: float = NewtonOptions.tol
    max_points: int = ContinuationOptions.max_points
    time_limit: float = 3600.0  # s per branch: a sweep that cannot go on stops, keeping its points
    kink_tol: float = NewtonOptions.relaxed_kink_tol  # residual accepted for a corrector stalled on a kink at the smallest steps
    # "sampled": the Jenkins law at the AFT's samples; "events": switches located between samples
    # and the forces integrated over the pieces (jointfem.contact._events; one tangential direction)
    aft: str = "sampled"
    # the band a branch may leave the sweep window into at a fold and still come back from (rad/s);
    # None: an octave each side of the window (jointfem.analysis.frf.default_omega_limits)
    omega_limits: tuple[float, float] | None = None
    # each located peak's truncation error, by the same peak at (3H, 2N) (analysis.frf.SweepOptions)
    peak_error: bool = False
    # every point's Floquet exponents: "auto", "on" or "off" (--stability, which overrides it)
    stability: str = "auto"
    # the exponents with the contact laws' memory (a stuck slider's e^(-s tau)); false: Hill's
    # matrix as the AFT's periodic Jacobian gives it, about a third of the stability's cost
    stability_memory: bool = True
    # each located peak searched until nothing can beat it by more than this share of its error bar
    # (analysis.frf.SweepOptions.peak_share); 0: to 1e-8 in omega, whatever the error bar
    peak_share: float = 0.1

    @property
    def omega_start(self) -> float:
        return self.omega_min if self.direction == "up" else self.omega_max

    @property
    def omega_end(self) -> float:
        return self.omega_max if self.direction == "up" else self.omega_min


@dataclass(frozen=True)
class NmaSpec:
    """The [nma] table: which nonlinear mode ``jointfem nma`` follows, over which amplitudes, and
    where the amplitude is measured (an output name; None: the model's first output)."""

    amplitude_range: tuple[float, float]  # m, first-harmonic amplitude at ``output``
    mode: int = 1  # the stuck linear mode, 1 = the lowest
    output: str | None = None
    # -xi M u' on every harmonic ("all", Krack 2015) or on the fundamental only (analysis.nma)
    self_excitation: str = "all"


@dataclass(frozen=True)
class ReductionSpec:
    """The [reduction] table: the model reduction a command uses when its --method (--modes,
    --tvd, --tvd-kind) is not given."""

    method: str = "full"  # one of rom.METHODS; "full": no reduction
    modes: int = ROM_MODES
    tvd: int = ROM_TVD
    tvd_kind: str = "eigen"


@dataclass(frozen=True)
class Scene:
    path: Path
    kind: str
    name: str
    solver: SolverSpec
    model: Any  # LumpedSpec | Beam2DSpec | ContinuumSpec
    data: dict  # the parsed TOML, for the record
    nma: NmaSpec | None = None  # the [nma] table, where the scene has one
    reduction: ReductionSpec = ReductionSpec()  # the [reduction] table (full order without one)


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
                raise SceneError(self.path, self.key(k), MISSING, "required key is missing")
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
        if v != 0 and not 1e-30 <= abs(v) <= 1e30:  # SI values of this field live far inside; beyond, K or M overflow
            self.fail(k, v, "must be 0 or of magnitude between 1e-30 and 1e30 (SI units)")
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

    def boolean(self, k: str, default=_REQUIRED) -> bool:
        v = self.raw(k, default)
        if not isinstance(v, bool):
            self.fail(k, v, "must be true or false")
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
        if not isinstance(v, dict):
            self.fail(k, v, "must be a table ([...] or { key = value, ... })")
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
    if not (1e-30 <= lo and hi <= 1e30):
        t.fail("omega_range", rng, "must lie between 1e-30 and 1e30 rad/s")
    if hi == lo:
        t.fail("omega_range", rng, "empty frequency range (omega_min == omega_max)")
    if hi < lo:
        t.fail("omega_range", rng, "reversed frequency range (omega_min > omega_max); use direction = \"down\" "
                                   "to sweep downwards")
    auto = t.has("harmonics") and t.data["harmonics"] == "auto"
    if auto:
        t.raw("harmonics")
        H = 3
    else:
        H = t.integer("harmonics", SolverSpec.harmonics, ge=1)
    target = t.number("harmonic_target", SolverSpec.harmonic_target, gt=0)
    H_max = t.integer("harmonics_max", SolverSpec.harmonics_max, ge=1)
    amp_tol = t.number("amplitude_tol", SolverSpec.amplitude_tol, gt=0)
    for key in ("harmonic_target", "harmonics_max", "amplitude_tol"):
        if not auto and t.has(key):
            t.fail(key, t.data[key], 'only with harmonics = "auto"')
    if auto and amp_tol >= 1:
        t.fail("amplitude_tol", amp_tol, "must be < 1 (a share of the largest amplitude)")
    if auto and target >= 1:
        t.fail("harmonic_target", target, "must be < 1 (a share of the contact force)")
    if auto and H_max < H:
        t.fail("harmonics_max", H_max, f"must be >= {H}, where harmonics = \"auto\" starts")
    N = t.integer("samples", default_samples(H_max if auto else H))
    if N < 2 * (H_max if auto else H) + 1:
        t.fail("samples", N, f"must be >= 2*{'harmonics_max' if auto else 'harmonics'}+1 = {2 * (H_max if auto else H) + 1}")
    ds_min, ds_max = t.number("ds_min", SolverSpec.ds_min, gt=0), t.number("ds_max", SolverSpec.ds_max, gt=0)
    limits = None
    if t.has("omega_limits"):
        lim = t.raw("omega_limits")
        if (not isinstance(lim, list) or len(lim) != 2 or not all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in lim)):
            t.fail("omega_limits", lim, "must be [low, high] in rad/s")
        if not (0 <= lim[0] <= lo and hi <= lim[1]):
            t.fail("omega_limits", lim, f"must contain omega_range = [{lo:g}, {hi:g}] (and low >= 0)")
        limits = (float(lim[0]), float(lim[1]))
    spec = SolverSpec(
        omega_min=lo, omega_max=hi, direction=t.string("direction", "up", choices=("up", "down")),
        harmonics=H, samples=N,
        # a first step the scene does not give stays within the scene's [ds_min, ds_max]
        ds0=t.number("ds0", min(max(SolverSpec.ds0, ds_min), ds_max), gt=0), ds_min=ds_min, ds_max=ds_max,
        tol=t.number("tol", SolverSpec.tol, gt=0), max_points=t.integer("max_points", SolverSpec.max_points, ge=2),
        kink_tol=t.number("kink_tol", SolverSpec.kink_tol, gt=0),
        time_limit=t.number("time_limit", SolverSpec.time_limit, gt=0), harmonics_auto=auto, harmonic_target=target,
        harmonics_max=H_max, amplitude_tol=amp_tol, samples_given=t.has("samples"), aft=t.string("aft", "sampled", choices=AFT_KINDS),
        omega_limits=limits, peak_error=t.boolean("peak_error", False),
        stability=t.string("stability", "auto", choices=("auto", "on", "off")),
        stability_memory=t.boolean("stability_memory", True), peak_share=t.number("peak_share", SolverSpec.peak_share, ge=0))
    if spec.peak_share > 1:
        t.fail("peak_share", spec.peak_share, "must be <= 1 (a share of the peak's error bar)")
    if spec.kink_tol > 1e-3:
        t.fail("kink_tol", spec.kink_tol, "must be <= 1e-3 (a residual of 0.1 % of the force)")
    if not spec.ds_min <= spec.ds0 <= spec.ds_max:
        t.fail("ds0", spec.ds0, f"must lie in [ds_min, ds_max] = [{spec.ds_min}, {spec.ds_max}]")
    t.done()
    return spec


def _nma(t: _Table) -> NmaSpec:
    rng = t.raw("amplitude_range")
    if (not isinstance(rng, list) or len(rng) != 2
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in rng)):
        t.fail("amplitude_range", rng, "must be [start, end] in m (first-harmonic amplitude at the output)")
    lo, hi = float(rng[0]), float(rng[1])
    if not 0 < lo < hi:
        t.fail("amplitude_range", rng, "must be 0 < start < end, m")
    if not (1e-30 <= lo and hi <= 1e30):
        t.fail("amplitude_range", rng, "must lie between 1e-30 and 1e30 m")
    spec = NmaSpec((lo, hi), mode=t.integer("mode", 1, ge=1), output=t.string("output", None),
                   self_excitation=t.string("self_excitation", "all", choices=("all", "fundamental")))
    t.done()
    return spec


def _reduction(t: _Table) -> ReductionSpec:
    from .rom.cms import TVD_KINDS
    from .rom.reductors import METHODS

    spec = ReductionSpec(method=t.string("method", "full", choices=METHODS),
                         modes=t.integer("modes", ROM_MODES, ge=0), tvd=t.integer("tvd", ROM_TVD, ge=0),
                         tvd_kind=t.string("tvd_kind", "eigen", choices=TVD_KINDS))
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
        # between names two masses (or a mass and ground), or, as a spring's does, two DOFs of one
        # axis (or a DOF and ground): that axis is then the tangential one unless given
        raw = t.strings("between", min_len=2, max_len=2)
        ab, named = [], set()
        for i, nd in enumerate(raw):
            mass, _, axis = nd.partition(".")
            if nd == GROUND and i == 1:
                ab.append(nd)
                continue
            if mass not in nodes:
                t.fail("between", nd, "no such mass" + (" (ground goes second)" if nd == GROUND else ""))
            if axis:
                _check_dofs(t, "between", [nd], known)
                named.add(axis)
            ab.append(mass)
        if len(named) > 1:
            t.fail("between", list(raw), "DOFs of different axes: a Jenkins element joins the same axis of both ends")
        tang = t.strings("tangential", tuple(named) if named else _REQUIRED, min_len=1, max_len=2)
        normal = t.string("normal", None)
        if named and not named <= set(tang) | {normal}:
            t.fail("between", list(raw), f"names axis {sorted(named)[0]!r}, which is neither tangential "
                   f"{list(tang)} nor normal ({normal})")
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
        jenkins.append(JenkinsSpec(ab[0], ab[1], tang, normal, kt, kn, t.number("mu", ge=0),
                                   _normal_preload(t, normal is not None, kn)))
        t.done()
    cubic = links("cubic_spring", "k3", {"gt": 0})
    unilateral = []
    for t in top.tables("unilateral_spring", required=False):
        ab = t.strings("between", min_len=2, max_len=2)
        if ab[0] == GROUND:
            t.fail("between", list(ab), "the first entry must be a DOF (ground goes second)")
        _check_dofs(t, "between", [x for x in ab if x != GROUND], known)
        if ab[0] == ab[1]:
            t.fail("between", list(ab), "a spring needs two different DOFs")
        unilateral.append(GapSpringSpec(ab[0], ab[1], t.number("k", gt=0), t.number("gap", 0.0, ge=0)))
        t.done()
    forces = []
    for t in top.tables("force"):
        dof = t.string("dof")
        _check_dofs(t, "dof", [dof], known)
        forces.append(ForceSpec(dof, t.number("amplitude", 0.0), t.number("phase", 0.0), t.number("static", 0.0)))
        t.done()
    if not any(f.amplitude for f in forces):
        top.fail("force", [f.dof for f in forces], "no force has a harmonic amplitude: nothing drives the sweep")
    out = top.table("output")
    outputs = out.strings("dofs")
    _check_dofs(out, "dofs", outputs, known)
    out.done()
    return LumpedSpec(tuple(masses), springs, dampers, tuple(jenkins), tuple(forces), outputs, cubic,
                      tuple(unilateral))


def _normal_preload(t: _Table, has_normal: bool, kn: float) -> float:
    """A Jenkins table's N0 (N, >= 0), or, with ``gap`` (m), a pair open at rest: N = kn (g_n - gap),
    that is N0 = -kn gap (JenkinsPairs)."""
    N0 = t.number("N0", 0.0 if t.has("gap") else _REQUIRED, ge=0)
    if not t.has("gap"):
        return N0
    gap = t.number("gap", ge=0)
    if not has_normal:
        t.fail("gap", gap, "an initial gap needs a normal axis (normal = ...) that can close it")
    if N0 > 0 and gap > 0:
        t.fail("gap", gap, f"a pair is either preloaded (N0 = {N0:g} N) or open by a gap, not both")
    return -kn * gap if gap > 0 else N0


SEMIDEFINITE_DENSE = 500  # up to this size a matrix's eigenvalues are computed whole (dense eigvalsh: 0.02 s)
SEMIDEFINITE_TOL = 1e-6  # negative eigenvalues down to this fraction of the largest are round-off


def _check_semidefinite(t: _Table, key: str, A, what: str) -> None:
    """A stiffness or mass matrix is positive semi-definite (a stiffness singular where the model
    floats free), to -SEMIDEFINITE_TOL of its largest eigenvalue.  A singular K exported with 8
    significant digits has entries off by up to 5e-9 of themselves, which moves its zero
    eigenvalues by up to |dK|_F <= 5e-9 sqrt(n) |K|_2, 2.7e-7 of the largest at n = 3000: a
    free-floating model must not be refused for that.  A negative diagonal entry disproves it at
    once (x = e_i gives x^T A x < 0).  Up to SEMIDEFINITE_DENSE DOFs the smallest eigenvalue is
    computed; above, the eigenvalues below the bound are counted by the inertia of A + tol I
    (linalg.eigenvalues_below): a sparse factorisation, as the modes' shift-invert makes anyway."""
    d = A.diagonal()
    if np.any(d < 0):
        i = int(np.argmin(d))
        t.fail(key, t.data[key], f"has a negative diagonal entry ({d[i]:.6g} at row {i}): not a {what} matrix "
                                 f"(x^T {key} x < 0 for x = e_{i})")
    if A.shape[0] <= SEMIDEFINITE_DENSE:
        lam = np.linalg.eigvalsh(A.toarray())
        if lam[0] < -SEMIDEFINITE_TOL * max(abs(lam[-1]), 1e-300):
            t.fail(key, t.data[key], f"is not positive semi-definite: its smallest eigenvalue is {lam[0]:.6g} "
                                     f"(largest {lam[-1]:.6g})")
        return
    import scipy.sparse.linalg as sla

    from .linalg import eigenvalues_below

    try:
        largest = float(sla.eigsh(A, k=1, which="LA", tol=1e-3, return_eigenvectors=False)[0])
    except sla.ArpackNoConvergence:  # the row-sum bound on it instead: a larger, more lenient shift
        largest = float(abs(A).sum(axis=1).max())
    count = eigenvalues_below(A, -SEMIDEFINITE_TOL * largest)
    if count is None:
        logging.getLogger(__name__).warning("%s: [matrices] %s: its definiteness was not checked (no symmetric "
                                            "factorisation)", t.path, key)
    elif count:
        t.fail(key, t.data[key], f"is not positive semi-definite: {count} eigenvalue{'s' * (count > 1)} "
                                 f"below {-SEMIDEFINITE_TOL:g} times the largest ({largest:.6g})")



def _matrices(top: _Table, path):
    """kind = "matrices": K, M (and D) from files, Jenkins pairs between DOFs (models.matrices)."""
    import scipy.sparse as sp

    from .models.matrices import DofPairSpec, MatricesSpec, MatrixFileError, read_matrix

    t = top.table("matrices")
    variables = t.raw("variables", {})
    if not isinstance(variables, dict):
        t.fail("variables", variables, "must be a table like {K = \"Kr\", M = \"Mr\"} (MATLAB variable names)")
    here = Path(str(path)).resolve().parent if Path(str(path)).is_file() else Path.cwd()
    mats = {}
    for key in ("K", "M", "D"):
        if key == "D" and not t.has("D"):
            continue
        f = t.string(key)
        try:
            mats[key] = read_matrix(here / f if not Path(f).is_absolute() else Path(f), variables.get(key))
        except MatrixFileError as exc:
            t.fail(key, f, str(exc))
    n = mats["K"].shape[0]
    for key, A in mats.items():
        if A.shape[0] != n:
            t.fail(key, t.data[key], f"is {A.shape[0]} x {A.shape[0]}, but K is {n} x {n}")
        if key in ("K", "M") and abs(A - A.T).max() > 1e-10 * max(abs(A).max(), 1e-300):
            t.fail(key, t.data[key], "is not symmetric (to 1e-10 of its largest entry)")
    if np.any(mats["M"].diagonal() <= 0):
        t.fail("M", t.data["M"], "has a diagonal entry <= 0: not a mass matrix")
    _check_semidefinite(t, "K", mats["K"], "stiffness")
    _check_semidefinite(t, "M", mats["M"], "mass")
    names = tuple(str(x) for x in t.raw("dof_names", [str(i) for i in range(n)]))
    if len(names) != n or len(set(names)) != n or GROUND in names:
        t.fail("dof_names", list(names), f"must be {n} different names (not 'ground')")
    t.done()
    known = set(names)

    def dof_pair(tt, key, value):
        if (not isinstance(value, list) or len(value) != 2 or str(value[0]) == GROUND
                or any(str(v) not in known and str(v) != GROUND for v in value) or str(value[0]) == str(value[1])):
            tt.fail(key, value, "must be [a, b]: two different DOFs of the model, b may be \"ground\"")
        return str(value[0]), str(value[1])

    jenkins = []
    for tt in top.tables("jenkins", required=False):
        tang = tt.raw("tangential")
        if not isinstance(tang, list) or not 1 <= len(tang) <= 2:
            tt.fail("tangential", tang, "must be a list of one or two [a, b] DOF pairs")
        tang = tuple(dof_pair(tt, "tangential", v) for v in tang)
        normal = dof_pair(tt, "normal", tt.raw("normal")) if tt.has("normal") else None
        kt = tt.number("kt", gt=0)
        kn = tt.number("kn", gt=0) if normal is not None else tt.number("kn", 0.0, ge=0)
        jenkins.append(DofPairSpec(tang, normal, kt, kn, tt.number("mu", ge=0), _normal_preload(tt, normal is not None, kn)))
        tt.done()
    forces = []
    for tt in top.tables("force"):
        dof = str(tt.raw("dof"))
        if dof not in known:
            tt.fail("dof", dof, "no such DOF")
        forces.append(ForceSpec(dof, tt.number("amplitude", 0.0), tt.number("phase", 0.0), tt.number("static", 0.0)))
        tt.done()
    if not any(f.amplitude for f in forces):
        top.fail("force", [f.dof for f in forces], "no force has a harmonic amplitude: nothing drives the sweep")
    out = top.table("output")
    outputs = tuple(str(x) for x in out.raw("dofs"))
    for o in outputs:
        if o not in known:
            out.fail("dofs", o, "no such DOF")
    out.done()
    D = mats.get("D")
    if top.has("damping"):
        if D is not None:
            top.fail("damping", top.data["damping"], "give D in [matrices] or a [damping] table, not both")
        dt = top.table("damping")
        dt.string("kind", choices=("rayleigh",))
        D = dt.number("alpha", ge=0) * mats["M"] + dt.number("beta", ge=0) * mats["K"]
        dt.done()
    if D is None:
        D = sp.csr_matrix((n, n))
    return MatricesSpec(mats["K"], mats["M"], sp.csr_matrix(D), names, tuple(jenkins), tuple(forces), outputs)


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


def _point(t: _Table, k: str, dim: int, box) -> tuple[float, ...]:
    v = t.raw(k)
    if (not isinstance(v, list) or len(v) != dim
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)):
        t.fail(k, v, f"must be a point of {dim} coordinates in m")
    lo, hi = box
    tol = 1e-9 * max(hi)
    if any(x < a - tol or x > b + tol for x, a, b in zip(v, lo, hi)):
        t.fail(k, v, f"lies outside the model's bounding box {list(lo)} .. {list(hi)} m")
    return tuple(float(x) for x in v)


def _continuum(top: _Table, kind: str, path):
    """[geometry], [mesh], [material], [contact], [damping], [force], [output] of a continuum scene."""
    from .fem.continuum import GEOMETRIES, Bolt, ContinuumSpec

    dim = 3 if kind == "continuum3d" else 2
    g = top.table("geometry")
    shape = g.string("shape", choices=GEOMETRIES)
    if shape == "brb" and dim != 3:
        g.fail("shape", shape, "the Brake-Reuss beam is 3D only (kind = \"continuum3d\")")
    brb, stack = shape == "brb", shape == "stack"
    geo = dict(geometry=shape, dim=dim,
               length=g.number("length", 0.42 if brb else 0.3, gt=0),
               height=g.number("height", 0.0254 if brb else 0.006, gt=0),
               width=g.number("width", 0.0254 if brb else 0.025, gt=0))
    if stack:  # the block lies on the base's whole top face
        if g.has("overlap"):
            g.fail("overlap", g.raw("overlap"), "a stack's block covers its base: its joint is the whole length")
        geo["overlap"] = geo["length"]
    else:
        geo["overlap"] = g.number("overlap", 0.12 if brb else 0.03, gt=0)
    if brb and geo["width"] != geo["height"]:
        g.fail("width", geo["width"], f"the Brake-Reuss section is square: must equal height = {geo['height']}")
    if shape not in ("bar", "stack") and not geo["overlap"] < geo["length"]:
        g.fail("overlap", geo["overlap"], f"must be < length = {geo['length']}")
    clamped = g.strings("clamped", () if brb else ("A",) if stack else ("A", "B"), min_len=0, max_len=2)
    for c in clamped:
        if c not in ("A", "B"):
            g.fail("clamped", list(clamped), "entries must be \"A\" (the base's bottom face) or \"B\" (the "
                   "block's top face)" if stack else "entries must be \"A\" (left end) or \"B\" (right end)")
    geo["clamped"] = ("A" in clamped, "B" in clamped)
    if shape == "bar" and not geo["clamped"][0]:
        g.fail("clamped", list(clamped), "the single bar is a cantilever: must include \"A\"")
    g.done()
    m = top.table("mesh")
    size = m.number("size", gt=0)
    size_normal = m.number("size_normal", size, gt=0)
    L = geo["length"]
    x_end = L if shape == "bar" else 2 * L - geo["overlap"]
    if x_end / size > 2000 or geo["height"] / size_normal > 200:
        m.fail("size", size, "gives more than 2000 elements along the bars: too fine for this tool")
    size_joint = m.number("size_joint", size, gt=0)
    if geo["width"] / size_joint > 2000:
        m.fail("size_joint", size_joint, "gives more than 2000 elements across the width: too fine for this tool")
    for key, h in (("size", size), ("size_joint", size_joint)):  # both mesh the joint along x
        if shape != "bar" and h > geo["overlap"] * (1 + 1e-9):
            m.fail(key, h, f"must be <= overlap = {geo['overlap']} m (at least one element in the joint)")
    structured = m.raw("structured", True)
    if not isinstance(structured, bool):
        m.fail("structured", structured, "must be true or false")
    if size_joint != size and not structured:
        m.fail("size_joint", size_joint, "refines the joint of structured meshes only (structured = true)")
    mesh_file = m.string("file", None)
    if mesh_file is not None and Path(mesh_file).suffix.lower() != ".msh":  # '' and a folder too
        m.fail("file", mesh_file, "must name a gmsh .msh file (written there if it does not exist)")
    if mesh_file is not None and not Path(mesh_file).is_absolute() and Path(str(path)).is_file():
        mesh_file = str((Path(str(path)).resolve().parent / mesh_file).resolve())  # relative to the scene file
    mesh = dict(size=size, size_normal=size_normal, size_joint=size_joint, degree=m.integer("degree", 2, ge=1),
                mesh_file=mesh_file, structured=structured)
    if mesh["degree"] > 2:
        m.fail("degree", mesh["degree"], "must be 1 or 2")
    if not structured and dim == 3 and mesh["degree"] == 2:
        m.fail("degree", 2, "unstructured 3D meshes need degree = 1: the corners of degree-2 triangles on the "
                            "contact faces get zero area (or use structured = true)")
    m.done()
    mat = top.table("material", required=False)
    material = dict(young=mat.number("young", 192.85e9 if brb else 2.1e11, gt=0),
                    poisson=mat.number("poisson", 0.29 if brb else 0.3, ge=0),
                    density=mat.number("density", 7857.8 if brb else 7850.0, gt=0))
    if not material["poisson"] < 0.5:
        mat.fail("poisson", material["poisson"], "must be < 0.5")
    mat.done()
    ymax = 2 * geo["height"] if shape in ("lap", "stack") else geo["height"]
    box = ((0.0, 0.0, 0.0)[:dim], (x_end, ymax, geo["width"])[:dim])
    contact = {}
    if shape != "bar":
        c = top.table("contact")
        contact = dict(kt=c.number("kt", 0.0, ge=0), kn=c.number("kn", 0.0, ge=0),
                       kt_total=c.number("kt_total", 0.0, ge=0), kn_total=c.number("kn_total", 0.0, ge=0),
                       mu=c.number("mu", ge=0), pressure=c.number("pressure", 0.0, ge=0))
        for k in ("kt", "kn"):
            if (contact[k] > 0) == (contact[k + "_total"] > 0):
                c.fail(k, contact[k], f"give exactly one of {k} (N/m^3, per contact area) and {k}_total "
                                      f"(N/m, the whole joint), > 0")
        bolts = []
        for b in c.tables("bolt", required=False):
            x = b.number("x")
            z = b.number("z", geo["width"] / 2)
            x0 = L - geo["overlap"]
            if not x0 <= x <= L:
                b.fail("x", x, f"must lie in the overlap [{x0}, {L}] m")
            if dim == 3 and not 0 <= z <= geo["width"]:
                b.fail("z", z, f"must lie in [0, {geo['width']}] m")
            bolts.append(Bolt(x, z, b.number("radius", gt=0), b.number("force", gt=0)))
            b.done()
        contact["bolts"] = tuple(bolts)
        contact["patches_only"] = bool(c.raw("patches_only", False))
        if not isinstance(c.data.get("patches_only", False), bool):
            c.fail("patches_only", c.data["patches_only"], "must be true or false")
        if contact["patches_only"] and not bolts:
            c.fail("patches_only", True, "needs at least one [[contact.bolt]]")
        # bolts load the outer faces through a static contact solve unless the scene asks for patches
        contact["preload"] = c.string("preload", "static" if bolts else "uniform", choices=("uniform", "static"))
        if contact["preload"] == "static":
            chosen = "" if c.has("preload") else " (the default with bolts; preload = \"uniform\" spreads each bolt's " \
                                                 "force over the contact nodes under it instead)"
            if not bolts:
                c.fail("preload", "static", "needs at least one [[contact.bolt]] (the bolts load the outer faces)")
            if contact["pressure"] > 0:
                c.fail("pressure", contact["pressure"], "with preload = \"static\" the pressure comes from the static "
                       f"contact solve: leave pressure out{chosen}")
            if contact["patches_only"]:
                c.fail("patches_only", True, f"with preload = \"static\" the static solve decides which pairs touch{chosen}")
        contact["preload_path"] = c.string("preload_path", "stuck", choices=("stuck", "frictionless"))
        if contact["preload_path"] != "stuck" and contact["preload"] != "static":
            c.fail("preload_path", contact["preload_path"], "is the static solve's loading path: it needs "
                                                           "preload = \"static\"")
        contact["gap"] = _gap_profile(c, dim, geo, path, contact) if c.has("gap") else None
        c.done()
    dm = top.table("damping", required=False)
    dm.string("kind", "rayleigh", choices=("rayleigh",))
    damping = dict(rayleigh_alpha=dm.number("alpha", 0.0, ge=0), rayleigh_beta=dm.number("beta", 0.0, ge=0))
    dm.done()
    comps = ("ux", "uy", "uz")[:dim]
    f = top.table("force", required=False)
    force = dict(force=f.number("amplitude", 1.0), force_dir=f.string("direction", "uy", choices=comps),
                 force_at=_point(f, "at", dim, box) if f.has("at") else (L / 2, 0.0, geo["width"] / 2)[:dim])
    f.done()
    out = top.table("output", required=False)
    pts = out.raw("points", {})
    if not isinstance(pts, dict):
        out.fail("points", pts, "must be a table name = [x, y(, z)]")
    pt = _Table(path, pts, out.key("points"))
    ocomps = out.strings("components", ("uy",))
    for cc in ocomps:
        if cc not in comps:
            out.fail("components", cc, f"must be one of {', '.join(comps)}")
    outputs = tuple((nm, _point(pt, nm, dim, box), cc) for nm in pts for cc in ocomps)
    out.done()
    if not outputs:  # the driving point
        outputs = (("drive", force["force_at"], force["force_dir"]),)
    supports = tuple(_support(s, dim, box) for s in top.tables("support", required=False))
    return ContinuumSpec(**geo, **mesh, **material, **contact, **damping, **force, outputs=outputs,
                         supports=supports, source=str(path))


def _gap_profile(c: _Table, dim: int, geo: dict, path, contact: dict):
    """[contact.gap]: the interface's initial gaps from its geometry (fem.continuum.GapProfile)."""
    from .fem.continuum import GapProfile

    t = c.table("gap")
    kind = t.string("kind", choices=("crown", "table"))
    L, W, x0 = geo["length"], geo["width"], geo["length"] - geo["overlap"]
    if contact["preload"] == "uniform" and (contact["pressure"] > 0 or contact["bolts"]):
        t.fail("kind", kind, "initial gaps need preload = \"static\" to say which pairs the bolts close (a "
                             "prescribed pressure cannot), or no preload at all")
    if kind == "crown":
        centre = t.raw("centre", [(x0 + L) / 2, W / 2][:dim - 1])
        if (not isinstance(centre, list) or len(centre) != dim - 1
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in centre)):
            t.fail("centre", centre, f"must be [x{', z' if dim == 3 else ''}] in m, where the faces touch")
        radius = t.number("radius", gt=0)
        t.done()
        return GapProfile("crown", tuple(float(v) for v in centre), radius)
    name = t.string("file")
    f = Path(name) if Path(name).is_absolute() else Path(str(path)).resolve().parent / name
    cols = ("x", "gap") if dim == 2 else ("x", "z", "gap")
    try:
        data = np.genfromtxt(f, delimiter=",", names=True, dtype=float, encoding="utf-8")
    except OSError as exc:
        t.fail("file", name, f"cannot be read ({exc.strerror or exc})")
    except ValueError as exc:
        t.fail("file", name, f"is not a CSV table with a header line ({exc})")
    if data.dtype.names is None or tuple(data.dtype.names) != cols:
        t.fail("file", name, f"must be a CSV table with the header {','.join(cols)} (m), "
                             f"got {','.join(data.dtype.names or ())}")
    rows = np.atleast_1d(data)
    pts = np.column_stack([rows[k] for k in cols])
    if pts.shape[0] < (2 if dim == 2 else 3) or not np.all(np.isfinite(pts)):
        t.fail("file", name, f"needs at least {2 if dim == 2 else 3} rows of finite numbers")
    bad = np.flatnonzero(pts[:, -1] < 0)
    if bad.size:
        t.fail("file", name, f"row {int(bad[0]) + 2} has gap = {pts[bad[0], -1]:g} m: gaps are >= 0 (an "
                             f"interference would be a preload)")
    t.done()
    return GapProfile("table", points=tuple(map(tuple, pts.tolist())), source=str(f))


def _support(s: _Table, dim: int, box):
    """One [[support]]: a soft spring to ground on an outer face (a bungee cord)."""
    from .fem.continuum import Support

    at = _point(s, "at", dim, box)
    lo, hi = box
    tol = 1e-9 * max(hi)
    if not any(abs(x - a) <= tol or abs(x - b) <= tol for x, a, b in zip(at, lo, hi)):
        s.fail("at", list(at), f"must lie on an outer face of the model's bounding box {list(lo)} .. {list(hi)} m "
                               f"(a support holds the surface)")
    k = s.raw("stiffness")
    k = [k] * dim if isinstance(k, (int, float)) and not isinstance(k, bool) else k
    if (not isinstance(k, list) or len(k) != dim or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and 0 <= x <= 1e30 for x in k)
            or not any(x > 0 for x in k)):
        s.fail("stiffness", s.data["stiffness"], f"must be a number or {dim} numbers >= 0 (N/m along "
                                                 f"{', '.join('xyz'[:dim])}), not all zero")
    sup = Support(at, tuple(float(x) for x in k), s.number("radius", 0.0, ge=0))
    s.done()
    return sup


def load_scene(path) -> Scene:
    """Read and validate a scene file.  Raises SceneError (one line) on any bad input."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise SceneError(path, "(file)", str(path), f"cannot be read: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise SceneError(path, "(file)", str(path), "is not a text file: a scene is TOML (UTF-8)") from None
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
    if kind == "lumped":
        model = _lumped(top)
    elif kind == "beam2d":
        model = _beam2d(top)
    elif kind == "matrices":
        model = _matrices(top, path)
    else:
        model = _continuum(top, kind, path)
    nma = _nma(top.table("nma")) if top.has("nma") else None
    reduction = _reduction(top.table("reduction")) if top.has("reduction") else ReductionSpec()
    top.done()
    if solver.aft == "events":
        _check_events(path, kind, model)
    return Scene(Path(str(path)), kind, name, solver, model, data, nma, reduction)


def _check_events(path, kind: str, model) -> None:
    """The event-accurate AFT has one tangential direction per pair: refuse a scene with two."""
    two = kind == "continuum3d" or (kind in ("lumped", "matrices") and any(
        len(j.tangential) == 2 for j in model.jenkins))
    if two:
        raise SceneError(path, "solver.aft", "events", "the event-accurate AFT has one tangential direction per "
                         "pair; this scene has pairs with two (3D contact): use aft = \"sampled\"")


def check_solvable(scene: Scene) -> None:
    """Refuse, before any expensive work, a nonlinear sweep that cannot have a solution.

    A continuum substructure without a clamp has rigid-body modes: once its joint slips or
    opens, nothing holds it, and the static (harmonic-0) problem is singular.
    """
    spec = scene.model
    if scene.kind == "lumped":
        _check_lumped_supports(scene)
    held = spec.supported() if scene.kind.startswith("continuum") and spec.geometry != "bar" else (True, True)
    if not all(held):
        free = [s for s, c in zip("AB", held) if not c]
        raise SceneError(scene.path, "geometry.clamped", [s for s, c in zip("AB", spec.clamped) if c],
                         f"substructure {' and '.join(free)} has no supports (rigid-body modes): a nonlinear "
                         f"sweep needs each substructure clamped or held by a [[support]] (soft springs, such as "
                         f"a free-free test's bungee cords)")


def _check_lumped_supports(scene: Scene) -> None:
    """Every DOF of a lumped model needs a path of linear springs to ground.  A DOF held only by
    a Jenkins element has an undetermined mean position once it slips (any offset of it and of
    its slider gives the same forces), and a DOF held by nothing has a singular stiffness."""
    spec = scene.model
    parent = {"ground": "ground"}

    def root(a):
        while parent.setdefault(a, a) != a:
            a = parent[a]
        return a

    for link in spec.springs:
        ra, rb = root(link.a), root(link.b)
        if link.value > 0 and ra != rb:
            if ra == "ground":
                parent[rb] = ra
            else:
                parent[ra] = rb
    free = [f"{m.name}.{d}" for m in spec.masses for d in m.dofs if root(f"{m.name}.{d}") != "ground"]
    if free:
        raise SceneError(scene.path, "spring", free[0],
                         f"DOF{'s' if len(free) > 1 else ''} {', '.join(free)} ha{'ve' if len(free) > 1 else 's'} "
                         f"no path of linear springs to ground (rigid-body motion): once a Jenkins element "
                         f"slips or opens, nothing fixes the mean position; add a spring to ground")


def create_structure(scene: Scene):
    """Build the physical model of a scene (only the kind it needs is imported), with the contact
    law's AFT that [solver] aft names."""
    structure = _create_structure(scene)
    if scene.solver.aft == "events":
        from .models.structure import with_event_aft
        structure = with_event_aft(structure)
    return structure


def _create_structure(scene: Scene):
    if scene.kind == "lumped":
        from .models.lumped import create_lumped
        return create_lumped(scene.model)
    if scene.kind == "beam2d":
        from .models.beam2d import create_beam2d
        return create_beam2d(scene.model)
    if scene.kind == "matrices":
        from .models.matrices import create_matrices
        return create_matrices(scene.model)
    from .fem.continuum import create_continuum
    return create_continuum(scene.model)
