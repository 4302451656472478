"""Conditional flow matching over hand poses: the second generative family beside the CVAE (``train.generator: flow``).

A velocity network v(x_t, t, c) learns straight paths from Gaussian noise x_0 ~ N(0, I) to a training pose x_1
(rectified flow): x_t = (1 - t) x_0 + t x_1, target velocity x_1 - x_0, t ~ U(0, 1). A new pose is the end of the ODE
dx/dt = v(x, t, c) from a noise draw at t = 0 to t = 1, in ``train.flow_steps`` Euler or Heun steps.

Everything around the network is the CVAE's (``network.GraspCVAE``, which ``GraspFlow`` extends): PointNet and its
condition c = [global feature, associated point's local feature], the pose frame at the associated point (the anchor),
the ``hand`` frame's roll input, the grasp type's one-hot, the 9 + J pose features (``model.pose``, translation in
tenths of a metre, 6D rotation, the hand's J joints in rad: 31 for the Shadow Hand). The velocity network works in the
pose frame, as the CVAE's decoder does.

So that the CVAE's sampling runs unchanged (``sampling.synthesize``: heading match, neighbour clouds, matched anchors,
types), the flow plays the CVAE's part through the same methods:

- ``decode(latent, ...)``: the latent is the noise x_0 (as wide as the features), integrated forward to a pose;
- ``encode(pose, ...)``: the pose integrated backward to its noise (log σ² = 0), which the learning ladder's
  reconstructions and dataset expansion decode again;
- its stored training codes keep each training grasp's condition, cloud and type, with mean 0 and log σ² 0, so the
  ``neighbours`` and ``aggregate`` priors draw x_0 ~ N(0, T² I) while still naming the training grasp whose associated
  point's local feature picks the anchor (``anchor_rule: matched``).

The training loss (``training.batch_loss``) is the velocity's squared error summed over the 9 + J features (logged as
``recon``; ``kl`` is 0), and the energy terms, when weighted, score the predicted clean pose x̂_1 = x_t + (1 - t) v.
"""

from __future__ import annotations

import dataclasses
import math

import torch

from dexlite_pipeline.model.config import FLOW_SOLVERS, GENERATORS, ModelConfig, TrainConfig
from dexlite_pipeline.model.network import GraspCVAE, _mlp
from dexlite_pipeline.model.pose import SHADOW_JOINT_COUNT, pose_feature_dim

CVAE, FLOW = GENERATORS
TIME_FREQUENCIES = 4  # sin and cos of 2πk t, k = 1..4, beside t itself: the velocity network's time input
TIME_FEATURES = 1 + 2 * TIME_FREQUENCIES


def flow_network_config(config: ModelConfig, joint_count: int = SHADOW_JOINT_COUNT) -> ModelConfig:
    """The network config a flow model records: ``config`` with the latent (the ODE's start) as wide as a pose's
    features (9 + ``joint_count``: 31 for the Shadow Hand)."""
    return dataclasses.replace(config, latent_dim=pose_feature_dim(joint_count))


def time_features(t: torch.Tensor) -> torch.Tensor:
    """(B, 9) the velocity network's time input for times ``t`` (B,) in [0, 1]: t, sin 2πkt, cos 2πkt (k = 1..4)."""
    angle = 2 * math.pi * t[:, None] * torch.arange(1, TIME_FREQUENCIES + 1, dtype=t.dtype, device=t.device)
    return torch.cat([t[:, None], angle.sin(), angle.cos()], dim=1)


class GraspFlow(GraspCVAE):
    """PointNet-conditioned flow-matching generator of hand poses, with the CVAE's interface (module docstring).

    ``steps`` ODE steps of rule ``solver`` (euler or heun) from t = 0 to 1 when decoding, and back when encoding.
    The velocity network has the decoder's hidden widths (``config.decoder_hidden``); ``encoder_hidden`` is unused.
    """

    def __init__(
        self, config: ModelConfig, type_vocabulary: tuple[str, ...] = (), steps: int = 8, solver: str = "heun", hand_record: dict | None = None
    ) -> None:
        if solver not in FLOW_SOLVERS or steps < 1:
            raise ValueError(f"flow: solver must be one of {', '.join(FLOW_SOLVERS)} and steps >= 1, got {solver!r}, {steps}")
        joint_count = len(hand_record["joint_names"]) if hand_record is not None else SHADOW_JOINT_COUNT
        super().__init__(flow_network_config(config, joint_count), type_vocabulary, hand_record)
        self.steps = int(steps)
        self.solver = solver

    def _build_networks(self, inputs: int) -> None:
        self.velocity_net = _mlp(self.pose_feature_dim + TIME_FEATURES + inputs, self.config.decoder_hidden, self.pose_feature_dim)

    def velocity(self, x: torch.Tensor, t: torch.Tensor, inputs: torch.Tensor) -> torch.Tensor:
        """(B, 9 + J) velocity at pose-frame features ``x`` (B, 9 + J), times ``t`` (B,) and network inputs (``_inputs``)."""
        return self.velocity_net(torch.cat([x, time_features(t.to(x.dtype)), inputs], dim=1))

    def integrate(self, x: torch.Tensor, inputs: torch.Tensor, start: float, end: float) -> torch.Tensor:
        """``x`` (B, 9 + J) carried along the learned ODE from time ``start`` to ``end`` (either direction) in ``steps`` steps."""
        h = (end - start) / self.steps
        for k in range(self.steps):
            t = torch.full((len(x),), start + k * h, dtype=x.dtype, device=x.device)
            v = self.velocity(x, t, inputs)
            if self.solver == "euler":
                x = x + h * v
            else:  # Heun: the mean of the velocities at the step's start and at its Euler end
                x = x + 0.5 * h * (v + self.velocity(x + h * v, t + h, inputs))
        return x

    def decode(
        self, latent: torch.Tensor, condition: torch.Tensor, anchor: torch.Tensor, grasp_type: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Pose features (B, 9 + J) in the object frame: noise ``latent`` (B, 9 + J) integrated from t = 0 to 1."""
        return self._from_frame(self.integrate(latent, self._inputs(condition, anchor, grasp_type), 0.0, 1.0), anchor)

    def encode(
        self, pose_features: torch.Tensor, condition: torch.Tensor, anchor: torch.Tensor, grasp_type: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(noise, log σ² = 0), each (B, 9 + J): poses (B, 9 + J, object frame) integrated back from t = 1 to 0."""
        noise = self.integrate(self._to_frame(pose_features, anchor), self._inputs(condition, anchor, grasp_type), 1.0, 0.0)
        return noise, torch.zeros_like(noise)

    def flow_loss(
        self, pose_features: torch.Tensor, condition: torch.Tensor, anchor: torch.Tensor, noise: torch.Tensor, time: torch.Tensor,
        grasp_type: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(predicted clean poses (B, 9 + J, object frame), squared velocity error per grasp (B,)) of poses ``pose_features``
        at times ``time`` (B,) on their straight paths from ``noise`` (B, 9 + J); noise and times are drawn by the caller."""
        target = self._to_frame(pose_features, anchor)
        t = time[:, None].to(target.dtype)
        x_t = (1.0 - t) * noise + t * target
        v = self.velocity(x_t, time, self._inputs(condition, anchor, grasp_type))
        clean = self._from_frame(x_t + (1.0 - t) * v, anchor)
        return clean, ((v - (target - noise)) ** 2).sum(dim=1)

    def forward(self, pose_features, condition, anchor, noise, grasp_type=None):
        raise TypeError("a flow model trains through flow_loss (noise and times), not the CVAE's reparameterized pass")

    def set_latent_codes(self, mu, log_var, condition=None, cloud=None, grasp_type=None) -> None:
        """The training grasps' conditions, clouds and types as ``GraspCVAE.set_latent_codes`` stores them, with every
        code N(0, I) (mean 0, log σ² 0): the flow's start is noise whatever training grasp a draw names."""
        super().set_latent_codes(torch.zeros_like(mu), torch.zeros_like(log_var), condition, cloud, grasp_type)


def make_generator(train: TrainConfig, type_vocabulary: tuple[str, ...] = (), hand_record: dict | None = None) -> GraspCVAE:
    """A fresh model of the family ``train.generator`` with the networks of ``train.model``, for the hand
    ``hand_record`` (None: the Shadow Hand)."""
    if train.generator == FLOW:
        return GraspFlow(train.model, type_vocabulary, train.flow_steps, train.flow_solver, hand_record)
    return GraspCVAE(train.model, type_vocabulary, hand_record)


def network_config(train: TrainConfig, joint_count: int = SHADOW_JOINT_COUNT) -> ModelConfig:
    """The network config a model of ``train.generator`` built from ``train.model`` for a hand of ``joint_count`` joints records."""
    return flow_network_config(train.model, joint_count) if train.generator == FLOW else train.model


def generator_family(model: GraspCVAE) -> str:
    """``cvae`` or ``flow``: the family a model belongs to (what its file records)."""
    return FLOW if isinstance(model, GraspFlow) else CVAE


def family_record(model: GraspCVAE) -> dict:
    """What a model file records of the family: {"generator": ..., and for a flow "flow": {"steps", "solver"}}."""
    if isinstance(model, GraspFlow):
        return {"generator": FLOW, "flow": {"steps": model.steps, "solver": model.solver}}
    return {"generator": CVAE}


def model_from_record(record: dict, config: ModelConfig, type_vocabulary: tuple[str, ...], hand_record: dict | None = None) -> GraspCVAE:
    """The empty model a file's ``family_record`` entries describe (no ``generator`` entry: a CVAE, as every file before
    the flow family), for the hand ``hand_record`` (None: the Shadow Hand)."""
    family = record.get("generator", CVAE)
    if family == FLOW:
        flow = record.get("flow") or {}
        return GraspFlow(config, type_vocabulary, int(flow.get("steps", 8)), str(flow.get("solver", "heun")), hand_record)
    if family != CVAE:
        raise ValueError(f"unknown generator family {family!r} (known: {', '.join(GENERATORS)})")
    return GraspCVAE(config, type_vocabulary, hand_record)
