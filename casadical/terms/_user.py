"""A cause of one's own: a term a user states in a terms file (:mod:`casadical.terms._definitions`).

Its effects are expressions of the pose (readings, loads, the moment about
joint 1, the measured point, data columns) and of its own parameters,
translated into CasADi symbols by :mod:`casadical.terms._expression`:

- ``angle``: added to a joint's reading, where the catalogue's joint errors act;
- ``frame``: a change of a joint's link frame after its link transform (Tx Ty Tz Rz Ry Rx);
- ``tool``: an offset of the measured point in the last link frame;
- ``base``: a change of the robot base right after the estimated base pose;
- ``point``: an offset of the measured point in the measurement frame.

Its parameters are named ``TERM.PARAM``; made a term of one session
(``axis_wobble@B``, :class:`~casadical.terms._local.SessionLocal`)
``TERM.PARAM@B``: its geometry changes switch themselves off at the other
sessions' poses (``gated``).
"""

from __future__ import annotations

from dataclasses import replace

import casadi as ca
import numpy as np

from .._format import g3, relative
from ..errors import DataFileError, TermsFileError
from ..parameters import Parameter
from ..robot import Robot
from . import _expression as ex
from ._base import Context, ErrorTerm
from ._cause import Cause
from ._definitions import TermDefinition

#: the effects that change the geometry (the others act on the readings or the measured point)
GEOMETRY_EFFECTS = ("frame", "tool", "base")


class UserTerm(ErrorTerm):
    """The term of a :class:`~casadical.terms._definitions.TermDefinition`.

    Not registered: a model specification finds it by name among the definitions it is given
    (:func:`casadical.model.parse_spec`'s ``user_terms``).
    """

    gated = True
    user = True

    def __init__(self, definition: TermDefinition, joints=None):
        self.definition = definition
        self.name = self.cause = definition.name
        #: a term of scope "session" describes the measurement session: a calibration taken to other data drops it
        self.session = definition.scope == "session"
        super().__init__(list(definition.joints) if definition.joints is not None else None)
        self.joints = None if definition.joints is None else list(definition.joints)

    @property
    def covariates(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(self.definition.columns())

    @property
    def joint(self) -> int | None:
        """The one joint the term names, if it names one."""
        return self.joints[0] if self.joints is not None and len(self.joints) == 1 else None

    def spec(self) -> str:
        return self.name

    def settings(self) -> dict:
        return {}

    def error(self, key: str | None, message: str) -> TermsFileError:
        return self.definition.error(key, message)

    def bind(self, robot: Robot) -> None:
        """Check the joints and names against the robot: joints that exist, revolute ones for ``angle``."""
        d = self.definition
        key = "joint" if d.one_joint else "joints"
        bad = [j for j in d.joints or () if not 1 <= j <= robot.n]
        if bad:
            raise self.error(key, f"joint {bad[0]} does not exist on {robot.name} (joints 1..{robot.n})")
        if "offset" in d.effects:
            j = d.joints[0]
            raise self.error("offset", f"joint {j} of {robot.name} is revolute: an offset effect (m) is for a "
                             "prismatic joint; a revolute joint's is an angle effect (rad)")
        for effect, exprs in d.effects.items():
            for k, e in enumerate(exprs):
                used = ex.joint_names(e)
                for kind in ("q", "tau"):
                    for j in sorted(used[kind]):
                        if j > robot.n:
                            raise self.error(self.key(effect, k), f"'{kind}{j}' is not a name an expression may "
                                             f"use: {robot.name} has joints 1..{robot.n}")

    def key(self, effect: str, k: int) -> str:
        return f"{effect}[{k}]" if len(self.definition.texts[effect]) > 1 or effect not in ("angle", "offset") \
            else effect

    def text(self, key: str) -> str:
        """The source text of the expression at ``key`` (``frame[3]``, ``angle``)."""
        effect, _, k = key.partition("[")
        return self.definition.texts[effect][int(k[:-1]) if k else 0]

    def parameters(self, robot: Robot) -> list[Parameter]:
        return [Parameter(f"{self.name}.{p.name}", p.start, p.unit, p.scale, self.name, self.joint,
                          group="user", lower=p.lower, upper=p.upper) for p in self.definition.parameters]

    # --- the expressions in CasADi ---------------------------------------------------------------

    def environment(self, ctx: Context, geom=None) -> dict:
        """Each name the term's expressions use, as a CasADi symbol or expression of the model."""
        d = self.definition
        env: dict = {}
        torques = None
        for name in d.names():
            joint = ex.joint_name(name)
            if name in d.parameter_names:
                env[name] = ctx.p[f"{self.name}.{name}"]
            elif name in ex.MOMENT_NAMES or (joint and joint[0] == "tau"):
                if torques is None:     # while the geometry is being changed: of the geometry so far
                    torques = ctx if ctx.geom is not None else replace(ctx, geom=geom, _frames=None, _torques=None)
                env[name] = moment(torques)["xyz".index(name[1])] if joint is None else \
                    torques.torques()[joint[1] - 1]
            elif joint:
                env[name] = ctx.q[joint[1] - 1]
            elif name in ex.POINT_NAMES:
                env.update(point_names(ctx.point))
            else:
                env[name] = ctx.cov[name]
        return env

    def values(self, ctx: Context, effect: str, geom=None) -> list:
        """The effect's expressions in CasADi, each recorded for the finiteness check of the data."""
        env = self.environment(ctx, geom)
        out = []
        for k, e in enumerate(self.definition.effects[effect]):
            v = e.casadi(env)
            out.append(v)
            ctx.checks.append((self, self.key(effect, k), v))
        return out

    def joint_offsets(self, ctx: Context) -> dict:
        if "angle" not in self.definition.effects:
            return {}
        return dict(zip(self.joints, self.values(ctx, "angle")))

    def geometry(self, ctx: Context, geom):
        effects = self.definition.effects
        if not set(GEOMETRY_EFFECTS) & set(effects):
            return geom
        gate = 1 if ctx.gate is None else ctx.gate
        if "tool" in effects:
            geom = replace(geom, tool=[t + gate * v for t, v in zip(geom.tool, self.values(ctx, "tool", geom))])
        if "frame" in effects:
            j = self.joints[0]
            links = dict(geom.links)
            links[j] = [a + gate * v for a, v in zip(links.get(j, [0.0] * 6), self.values(ctx, "frame", geom))]
            geom = replace(geom, links=links)
        if "base" in effects:
            geom = replace(geom, mount=[a + gate * v for a, v in
                                        zip(geom.mount or [0.0] * 6, self.values(ctx, "base", geom))])
        return geom

    def base_offset(self, ctx: Context):
        if "point" not in self.definition.effects:
            return None
        return ca.vertcat(*self.values(ctx, "point"))

    def covariate_values(self, data) -> dict:
        """``row`` (each pose's place in its file, from 0) and a check that every column the term reads is there.

        Raises
        ------
        DataFileError
            The data lack a column the term reads.
        """
        out = {}
        for c in self.covariates:
            if c == "row":
                out[c] = np.asarray(data.rows, dtype=float)
            elif data.get(c) is None:
                raise DataFileError(f"has no numeric {c} column, which the user term {self.name!r} reads "
                                    f"({self.definition.file})", file=data.path, column=c)
        return out


def moment(ctx: Context) -> list:
    """The moment of the weights joint 1 carries (links and payload) about the origin of joint 1's frame, base
    frame (N m)."""
    robot, frames = ctx.robot, ctx.frames()
    g = ca.DM(robot.gravity)
    total = ca.SX.zeros(3, 1)
    o = frames.origin[0] if robot.n else ca.SX.zeros(3, 1)
    for i, j in enumerate(robot.joints):
        R, t = frames.link[i]
        total = total + ca.cross(t + ca.mtimes(R, ca.DM(j.com)) - o, j.mass * g)
    R, t = frames.tool
    total = total + ca.cross(t + ca.mtimes(R, ca.DM(robot.payload_com)) - o, ctx.cov["payload_kg"] * g)
    return [total[k] for k in range(3)]


def point_names(xyz) -> dict:
    """``px, py, pz`` (m) and ``azimuth, elevation`` (rad), ``distance`` (m) of the model's point."""
    px, py, pz = xyz[0], xyz[1], xyz[2]
    horizontal = ca.sqrt(px * px + py * py)
    return {"px": px, "py": py, "pz": pz, "azimuth": ca.atan2(py, px), "elevation": ca.atan2(pz, horizontal),
            "distance": ca.sqrt(px * px + py * py + pz * pz)}


def user_terms(terms) -> list[UserTerm]:
    """The user terms among ``terms`` (those of one session too)."""
    return [t for t in (getattr(t, "inner", t) for t in terms) if isinstance(t, UserTerm)]


class UserCauses(Cause):
    """The causes of the user's own (the terms of a terms file): a candidate of one carries its term's name as
    its cause and its parameters' names (``user``); one object answers for them all."""

    name = "user"
    order = 90

    def unexplained_item(self, cand, values, linear) -> dict:
        fitted = ", ".join(f"{n} = {values[n]:.4g}" for n in cand.parameter_names() if n in values)
        return {"what": f"a part the user term {cand.cause} describes ({fitted}, SI units)"}

    def figure(self, cand, data, model, params, linear) -> dict | None:
        """A term of no joint: the errors against the rows; of a joint: its angle (or axis) error against the
        joint's gravity torque (or position), with the first parameter's value as its effect."""
        if cand.joint is None:
            return None
        j = cand.joint
        value = params[cand.parameter_names()[0]].value
        if linear:
            q = data.q[:, j - 1]
            return {"x": q * 1000.0, "xlabel": f"axis {j} position (mm)", "effect": value * q}
        x = model.torques(data.q, params.values, model.covariates(data))[:, j - 1]
        return {"x": x, "xlabel": f"gravity torque at joint {j} (N m)", "effect": value * np.sign(x)}

    def short_name(self, cand) -> str:
        return cand.cause.replace("_", " ")

    def size(self, cand, values, stds, params, linear) -> str:
        """Its parameters as the parameter table reads them (``a2 = 0.017 deg +- 5.5 %``)."""
        return ", ".join(f"{p.name.split('.', 1)[-1]} = {g3(p.to_reading(p.value))} {p.reading_unit}"
                         + relative(p.std, p.value) for p in params)

    def parameter_names(self, cand) -> list[str]:
        return list(cand.user)

    def terms(self, cands) -> list[ErrorTerm]:
        """Each user term of ``cands`` once, by their names (each candidate carries its term's definition)."""
        definitions = {c.cause: c.definition for c in self.mine(cands)}
        return [UserTerm(definitions[name]) for name in sorted(definitions)]


#: the causes of the user's own (not in :data:`~casadical.terms._cause.CAUSES`: their names are the user's)
USER = UserCauses()
