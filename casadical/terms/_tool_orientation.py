"""Orientation of the measured probe on the flange: what full-pose (6-DoF) measurements add to the model."""

from __future__ import annotations

from ..kinematics import compose, rotx, roty, rotz
from ..parameters import Parameter
from ..robot import Robot
from ._base import Context, ErrorTerm, register

ANGLE_SCALE = 1e-3    # 1 mrad


@register
class ToolOrientation(ErrorTerm):
    """The probe's mounting rotation on the flange (last link frame): ``tool_roll, tool_pitch, tool_yaw``.

    A 6-DoF probe (laser-tracker T-Mac, or any sensor that measures its own
    orientation) is mounted on the flange at a rotation no robot file gives.
    The model's probe orientation in the measurement frame is

        base rotation x flange rotation (every term) x Rz(yaw) Ry(pitch) Rx(roll) x R0

    where ``R0`` is a reference mounting the calibration finds in closed form
    (kept with the calibration, like ``base0`` for the base pose) and the
    three parameters are small deviations from it, about the flange's own
    axes. The term changes no position: a position-only model never has it.
    ``calibrate`` adds it when the data have measured orientations
    (``rx_deg, ry_deg, rz_deg``), and estimates it always, like the base pose.
    """

    name = "tool_orientation"
    aliases = ("orientation",)
    cause = "geometric"
    is_cause = False
    superset_order = 12

    @classmethod
    def superset(cls, robot: Robot) -> list:
        return [cls()]

    def __init__(self, joints=None):
        super().__init__(None)

    def bind(self, robot: Robot) -> None:
        pass

    def spec(self) -> str:
        return self.name

    def settings(self) -> dict:
        return {}

    def parameters(self, robot: Robot) -> list[Parameter]:
        return [Parameter(f"tool_{k}", 0.0, "rad", ANGLE_SCALE, self.name, None, "mount")
                for k in ("roll", "pitch", "yaw")]

    def tool_rotation(self, ctx: Context):
        p = ctx.p
        return compose(rotz(p["tool_yaw"]), roty(p["tool_pitch"]), rotx(p["tool_roll"]))[0]
