"""Study protocols: what a Monte Carlo study simulates, selects and compares (TOML).

A study names a robot and its hidden truth (or a simulation protocol of
``problems/protocols`` that does), the pose plans that choose calibration
poses, the methods that calibrate on them, and how many repetitions to run
from one seed. The keys are documented in docs/formats.md (section 5); every
invalid key gives one line naming the file and the key.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

from ..data._simulate import (
    MAX_POSES,
    Effects,
    TomlValidator,
    effects_from_table,
    load_protocol,
    resolve_path,
    workspace_from_table,
)
from ..errors import CasadicalError, InputError
from ..loading import load_robot
from ..model._symbolic import Model
from ..planning._selectors import METHODS as SELECTORS
from ..robot import PROBLEMS, Robot, robot_from_dict, robot_to_dict
from ..runtime._files import named_toml, read_toml
from ._touch import TouchSpec, touch_from_table, touch_plan

STUDY_DIR = PROBLEMS / "studies"
#: most repetitions a protocol may ask for (the studies of docs/studies.md run 40-200; a run keeps a few
#: bytes per repetition, so the bound keeps its memory under a hundred MB)
MAX_REPETITIONS = 1_000_000
SOLVERS = ("ipopt", "lm", "gn", "auto")
_TOP_KEYS = {"name", "description", "protocol", "robot", "seed", "repetitions", "validation_poses",
             "extra_poses", "truth", "workspace", "plan", "method", "touch"}
_PLAN_KEYS = {"name", "method", "poses", "pool", "model", "ga_generations", "placements", "rows_per_point"}
_METHOD_KEYS = {"name", "method", "settings", "model", "solver"}


@dataclass
class PlanSpec:
    """How a repetition chooses its calibration poses.

    Attributes
    ----------
    name : str
        The results' ``plan`` column.
    selector : {"random", "d-optimal", "ga"}
    poses : tuple of int
        Numbers of poses to select (one plan per size).
    pool : int or None
        Candidates to select from (simulated and measured once per
        repetition, shared by the plans with the same pool size); None:
        ``random`` draws its poses directly.
    model : str
        Model whose parameters the ``d-optimal`` and ``ga`` selectors design for.
    ga_generations : int
    placements : int
        A touch plan's placements of the block (0: not a touch plan; :mod:`casadical.study._touch`); its
        ``poses`` are then the calibration rows, ``placements x sockets x rows_per_point``, and its ``pool`` the
        candidates per socket and placement ``d-optimal`` chooses from.
    rows_per_point : tuple of int
        A touch plan's rows per socket and placement, one plan per number.
    """

    name: str
    selector: str
    poses: tuple[int, ...]
    pool: int | None = None
    model: str = "kinematic+compliance"
    ga_generations: int = 100
    placements: int = 0
    rows_per_point: tuple[int, ...] = ()

    def pool_size(self, m: int) -> int:
        """Size of the candidate pool the ``m``-pose plan draws from."""
        return self.pool if self.pool is not None else m


@dataclass
class MethodSpec:
    """A calibration method of the study: a registered method or a plain model specification.

    Attributes
    ----------
    name : str
        The results' ``method`` column.
    method : str or None
        Registered method (:func:`casadical.methods.method_names`) ...
    settings : dict
        ... with these settings;
    model : str or None
        or a model specification calibrated by :func:`casadical.calibrate` ...
    solver : str
        ... with this solver.
    """

    name: str
    method: str | None = None
    settings: dict = field(default_factory=dict)
    model: str | None = None
    solver: str = "ipopt"


@dataclass
class Study:
    """A parsed study protocol.

    Attributes
    ----------
    name, description : str
    robot : Robot
    effects : Effects
        The hidden truth every repetition draws a robot from.
    workspace : dict
        Pose filter (:func:`casadical.data._simulate.sample_poses` options).
    seed : int
        Study seed; repetition ``r`` draws everything from ``(seed, r)``.
    repetitions : int
    validation_poses : int
        Independent validation poses per repetition.
    extra_poses : int
        Poses of the extra set (the TLBO paper's network set), 0 for none.
    plans : list of PlanSpec
    methods : list of MethodSpec
    path, text : str
        The protocol file and its text, kept with the results.
    touch : TouchSpec or None
        A study of touch protocols (its ``[touch]`` table): the block, the contact noise, the fresh placements
        each calibration is judged on (:mod:`casadical.study._touch`).
    """

    name: str
    robot: Robot
    effects: Effects
    workspace: dict
    seed: int
    repetitions: int
    validation_poses: int
    plans: list[PlanSpec]
    methods: list[MethodSpec]
    extra_poses: int = 0
    description: str = ""
    path: str = ""
    text: str = ""
    touch: TouchSpec | None = None

    def cells(self) -> list[tuple[PlanSpec, int]]:
        """(plan, number of poses) in protocol order: the plans of one repetition."""
        return [(p, m) for p in self.plans for m in p.poses]

    @property
    def rows_per_repetition(self) -> int:
        return len(self.cells()) * len(self.methods)

    def digest(self) -> str:
        """Fingerprint of everything that decides the rows (not the number of repetitions).

        Results of a study resume only into a folder with the same digest;
        raising ``repetitions`` extends a finished study.
        """
        # a touch study's keys only where there are some: the digests of the studies before them stay
        plans = [{k: v for k, v in asdict(p).items() if self.touch or k not in ("placements", "rows_per_point")}
                 for p in self.plans]
        doc = {"robot": robot_to_dict(self.robot), "effects": asdict(self.effects), "workspace": self.workspace,
               "seed": self.seed, "validation_poses": self.validation_poses, "extra_poses": self.extra_poses,
               "plans": plans, "methods": [asdict(m) for m in self.methods],
               **({"touch": asdict(self.touch)} if self.touch else {})}
        text = json.dumps(doc, sort_keys=True, default=repr)
        return hashlib.sha256(text.encode()).hexdigest()


def study_path(spec: str | Path) -> Path:
    """A study file by path, or by name in ``problems/studies``."""
    return named_toml(spec, STUDY_DIR, "no such study protocol file, and not a bundled study (bundled: {known})")


def load_study(spec: str | Path) -> Study:
    """Read and validate a study protocol (a path, or a name in ``problems/studies``).

    Raises
    ------
    InputError
        Any invalid key, in one line naming the file and the key (e.g.
        ``column 'plan[2].pool'``); unknown methods, model specifications
        and settings are found here, before any work.
    """
    path = study_path(spec)
    file = str(path)
    d = read_toml(path)
    v = TomlValidator(file)
    v.keys(d, _TOP_KEYS, "")
    if "protocol" in d:
        for k in ("robot", "truth", "workspace"):
            if k in d:
                raise InputError("give either protocol or robot/[truth]/[workspace], not both", file=file, column=k)
        proto = load_protocol(resolve_path(v.string(d, "protocol", "", required=True), path))
        robot, effects, workspace, seed = proto.robot, proto.effects, proto.workspace, proto.seed
    else:
        robot = _robot(d, path)
        effects = effects_from_table(v.table(d, "truth", ""), robot, file)
        workspace = workspace_from_table(v.table(d, "workspace", ""), file)
        seed = 0
    touch = touch_from_table(v.table(d, "touch", ""), v) if "touch" in d else None
    return Study(
        name=v.string(d, "name", "", default=path.stem),
        description=v.string(d, "description", "", default=""),
        robot=robot, effects=effects, workspace=workspace,
        seed=v.integer(d, "seed", "", default=seed, minimum=0),
        repetitions=v.integer(d, "repetitions", "", required=True, minimum=1, maximum=MAX_REPETITIONS),
        validation_poses=v.integer(d, "validation_poses", "", required=True, minimum=1, maximum=MAX_POSES),
        extra_poses=v.integer(d, "extra_poses", "", default=0, minimum=0, maximum=MAX_POSES),
        plans=_plans(d, robot, v, touch),
        methods=_methods(d, robot, v, touch),
        path=file, text=path.read_text(encoding="utf-8", errors="replace"), touch=touch)


def _robot(d: dict, path: Path) -> Robot:
    if "robot" not in d:
        raise InputError("missing required key (a robot name, robot file or [robot] table; or protocol)",
                         file=str(path), column="robot")
    if isinstance(d["robot"], dict):
        return robot_from_dict(d["robot"], str(path))
    if not isinstance(d["robot"], str):
        raise InputError(f"must be a robot name, a robot file or a table, got {d['robot']!r}", file=str(path),
                         column="robot")
    return load_robot(resolve_path(d["robot"], path))


def _tables(d: dict, key: str, v: TomlValidator) -> list[dict]:
    items = d.get(key)
    if not isinstance(items, list) or not items or not all(isinstance(t, dict) for t in items):
        raise InputError(f"needs at least one [[{key}]] table", file=v.file, column=key)
    return items


def _check_model(spec: str, robot: Robot, file: str, column: str) -> str:
    if not isinstance(spec, str):
        raise InputError(f"must be a model specification string, got {spec!r}", file=file, column=column)
    try:
        Model(robot, spec, jit=False)
    except CasadicalError as e:
        raise InputError(str(e), file=file, column=column) from e
    return spec


def _plans(d: dict, robot: Robot, v: TomlValidator, touch: TouchSpec | None = None) -> list[PlanSpec]:
    plans: list[PlanSpec] = []
    for i, t in enumerate(_tables(d, "plan", v), start=1):
        where = f"plan[{i}]"
        v.keys(t, _PLAN_KEYS, where)
        selector = v.string(t, "method", where, required=True)
        if selector not in SELECTORS:
            raise InputError(f"unknown pose selection method {selector!r}; choose from {', '.join(SELECTORS)}",
                             file=v.file, column=f"{where}.method")
        if touch is not None:
            placements, rows, pool = touch_plan(t, where, selector, touch, v)
            model = _check_model(t.get("model", "kinematic"), robot, v.file, f"{where}.model")
            plans.append(PlanSpec(name=v.string(t, "name", where, default=selector), selector=selector,
                                  poses=tuple(placements * len(touch.points) * r for r in rows), pool=pool,
                                  model=model, placements=placements, rows_per_point=rows))
            continue
        for key in ("placements", "rows_per_point"):
            if key in t:
                raise InputError("a plan of touches: the study needs a [touch] table (the block and its sockets)",
                                 file=v.file, column=f"{where}.{key}")
        raw = t.get("poses")
        sizes = raw if isinstance(raw, list) else [raw]
        if raw is None or not sizes or any(isinstance(m, bool) or not isinstance(m, int) or m < 1 for m in sizes):
            raise InputError(f"must be a whole number >= 1 or a list of them, got {raw!r}", file=v.file,
                             column=f"{where}.poses")
        if max(sizes) > MAX_POSES:
            raise InputError(f"must be at most {MAX_POSES:,} poses, got {max(sizes):,}", file=v.file,
                             column=f"{where}.poses")
        if len(set(sizes)) != len(sizes):
            raise InputError(f"lists a number of poses twice: {sizes}", file=v.file, column=f"{where}.poses")
        pool = v.integer(t, "pool", where, default=None, minimum=1, maximum=MAX_POSES)
        if pool is None and selector != "random":
            raise InputError(f"{selector} selects from a pool of candidates: give pool = N", file=v.file,
                             column=f"{where}.pool")
        if pool is not None and pool < max(sizes):
            raise InputError(f"the pool ({pool}) must hold at least the {max(sizes)} poses to select",
                             file=v.file, column=f"{where}.pool")
        model = _check_model(t.get("model", PlanSpec.model), robot, v.file, f"{where}.model")
        plans.append(PlanSpec(name=v.string(t, "name", where, default=selector), selector=selector,
                              poses=tuple(sizes), pool=pool, model=model,
                              ga_generations=v.integer(t, "ga_generations", where, default=100, minimum=1)))
    _unique([p.name for p in plans], "plan", v.file)
    return plans


def _methods(d: dict, robot: Robot, v: TomlValidator, touch: TouchSpec | None = None) -> list[MethodSpec]:
    from ..methods import lookup, make_method

    methods: list[MethodSpec] = []
    for i, t in enumerate(_tables(d, "method", v), start=1):
        where = f"method[{i}]"
        v.keys(t, _METHOD_KEYS, where)
        if ("method" in t) == ("model" in t):
            raise InputError("give either method (a registered method) or model (a model specification)",
                             file=v.file, column=where)
        if touch is not None and "method" in t:
            raise InputError("a [touch] study calibrates with model = \"...\" (a model specification); the "
                             "registered methods take tracker rows", file=v.file, column=f"{where}.method")
        if "method" in t:
            if "solver" in t:
                raise InputError("only with model; registered methods take settings", file=v.file,
                                 column=f"{where}.solver")
            settings = v.table(t, "settings", where)
            try:
                name = lookup(v.string(t, "method", where)).name
                make_method(name, **settings)
            except InputError as e:
                raise InputError(e.message, file=v.file, column=f"{where}.method") from e
            methods.append(MethodSpec(name=v.string(t, "name", where, default=name), method=name,
                                      settings=dict(settings)))
        else:
            if "settings" in t:
                raise InputError("only with method; a model takes solver", file=v.file, column=f"{where}.settings")
            model = _check_model(t["model"], robot, v.file, f"{where}.model")
            solver = v.string(t, "solver", where, default="ipopt")
            if solver not in SOLVERS:
                raise InputError(f"unknown solver {solver!r}; choose from {', '.join(SOLVERS)}", file=v.file,
                                 column=f"{where}.solver")
            methods.append(MethodSpec(name=v.string(t, "name", where, default=model), model=model, solver=solver))
    _unique([m.name for m in methods], "method", v.file)
    return methods


def _unique(names: list[str], key: str, file: str) -> None:
    for i, n in enumerate(names):
        if n in names[:i]:
            raise InputError(f"two [[{key}]] tables are named {n!r}; give each its own name", file=file,
                             column=f"{key}[{i + 1}].name")

