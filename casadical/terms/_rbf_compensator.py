"""The RBF compensator: a fitted RBF network adds the structure no named cause explains."""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..errors import ModelError
from ..robot import Robot
from ._base import Context, ErrorTerm, register


@register
class RBFCompensator(ErrorTerm):
    """A Gaussian RBF network from joint angles and gravity torques to a tool-point offset.

    The network (:class:`casadical.compensators.RBFNetwork`) is fitted to
    the residuals of a calibrated model, in the robot base frame (so the
    offset turns with the base pose and holds when the tracker moves), and
    then frozen: the term has no parameters of its own. Its features per
    pose are ``sin q``, ``cos q`` and the gravity torques of the model;
    it is part of the symbolic model, so predictions and joint-space
    Jacobians include it.

    Parameters
    ----------
    network : RBFNetwork or dict, optional
        A fitted network or its :meth:`~RBFNetwork.to_dict`; without one
        the term adds nothing (``calibrate`` fits it).
    """

    name = "rbf_compensator"
    aliases = ("rbf",)
    cause = "unexplained"
    is_cause = False
    covariates = ("payload_kg",)

    def __init__(self, joints=None, network=None):
        super().__init__(None)
        if isinstance(network, dict):
            from ..compensators import RBFNetwork
            from ..errors import InputError
            try:
                network = RBFNetwork.from_dict(network)
            except InputError as e:
                raise ModelError(f"rbf_compensator: {e}") from e
        self.network = network

    def spec(self) -> str:
        return self.name

    def settings(self) -> dict:
        return {"network": self.network.to_dict() if self.network is not None else None}

    def bind(self, robot: Robot) -> None:
        super().bind(robot)
        if self.network is not None and self.network.n_features_in_ != 3 * robot.n:
            raise ModelError(f"rbf_compensator: the network reads {self.network.n_features_in_} features, "
                             f"{robot.name} gives {3 * robot.n} (sin q, cos q, torques)")

    def robot_frame_offset(self, ctx: Context):
        if self.network is None:
            return None
        x = ca.vertcat(ca.sin(ctx.q), ca.cos(ctx.q), *ctx.torques())
        return self.network.casadi(x)


def features(q: np.ndarray, torques: np.ndarray) -> np.ndarray:
    """The RBF compensator's features of poses: ``sin q, cos q, torques`` (N, 3n)."""
    return np.column_stack([np.sin(q), np.cos(q), torques])
