"""PointNet object encoder and the conditional VAE over hand poses (Dex1B; the appendix of the DexLite write-up by Murali).

- PointNet: shared 1-D convolutions 3 -> 64 -> 128 -> 1024 -> 256 (6 input channels with
  ``point_normals``: each point's outward normal beside its position), each followed by a
  normalization and a leaky ReLU except the last; max-pooling over points gives the global
  feature, and the last layer's per-point features give the *local* feature of the
  grasp's associated point. Condition c = [global, local] (512 in the reference sizes).
- Encoder: [pose features, c] -> hidden layers -> (mu, log sigma^2) of the latent.
  Decoder: [z, c] -> hidden layers -> pose features (``model.pose``: 9 + J, 6D rotation, J the hand's joints).
- The hand: a model is for one hand (``hand_record``: its name and joint names in pose order, as grasp stores record
  it, ``io.grasp_store``); its pose features are 9 + J wide (31 for the Shadow Hand, the default).
- ``pose_frame`` is the frame in which the networks see the palm pose: ``object`` (the
  object's own frame), ``point`` (translation measured from the associated point, the
  *anchor*), ``surface`` (translation and rotation in a frame at the anchor: x along
  its outward normal, y horizontal, z = x × y) or ``hand`` (the same, but y is the palm's
  lateral axis projected onto the tangent plane, and the networks also read which way
  is up in that frame). A grasp closes on its anchor, so in the surface frames the
  decoder learns how a hand sits on a patch of surface, which carries over to unseen
  objects and to an object turned about the vertical axis; in the object frame it has to
  learn each training object's extent and orientation.
- Grasp types (``model.type_condition``): a model trained on several types also reads a one-hot of the grasp's
  type beside the condition, in the encoder and the decoder, over its vocabulary (``grasp_types``); a model
  trained on one type (or before types existed) reads none.
- Why ``hand``: grasps on one patch of surface come at every roll about the normal
  (thumb up, thumb down, ...). In the ``surface`` frame that roll is a many-modal target
  only the latent could carry, and the latent carries little once the energies shape the
  decoder (docs/results.md, "The model's fit"). In the ``hand`` frame the roll is an input,
  taken from the grasp in training and drawn uniformly at sampling (``sampling_anchors``).

Normalization: BatchNorm over the points of one cloud standardizes each cloud on its
own when a batch holds a single object, which erases the object's size and position
(the features become invariant to them) and makes training statistics differ from
the running ones used at sampling time. GroupNorm does the same per cloud in every
mode. So BatchNorm (the write-up's; ``config/profiles/writeup_gpu.yaml``) needs several
clouds per batch (``train.clouds_per_batch`` >= 2, see ``training``) and its running
statistics are used at sampling; the default profile trains one cloud per batch and
uses ``"none"`` (no normalization).
Point coordinates enter in tenths of a metre (``pose.TRANSLATION_UNIT_M``).
"""

from __future__ import annotations

import torch
from torch import nn

from dexlite_pipeline.model.hand_match import shadow_hand_record
from dexlite_pipeline.model.pose import STORED_JOINTS_START, TRANSLATION_UNIT_M, features_to_parts, parts_to_features, pose_feature_dim, shift_translation
from dexlite_pipeline.model.config import ModelConfig
from dexlite_pipeline.model.refiner import reading_width, surface_reading
from dexlite_pipeline.model.type_condition import known_types

# PointNet's hidden activations leak a little below zero: with plain ReLU and no normalization the
# 1024-wide layer can die during training (every unit negative for every point), after which every
# cloud gets the same global and local feature and the model ignores the object.
POINTNET_NEGATIVE_SLOPE = 0.01
LATERAL_AXIS = 0  # column of the palm rotation across the knuckles, little finger -> first finger


class PointNet(nn.Module):
    """Per-point shared MLP with max-pooling: (C, N, 3 or 6) clouds -> global (C, F), per-point (C, N, F).

    With ``normals`` each point enters with its outward normal (clouds of 6 channels), so
    the associated point's local feature tells which way the surface faces there.
    """

    def __init__(self, widths: tuple[int, ...], normalization: str = "batch", normals: bool = False) -> None:
        super().__init__()
        self.normals = normals
        layers: list[nn.Module] = []
        channels = 6 if normals else 3
        for i, width in enumerate(widths):
            layers.append(nn.Conv1d(channels, width, kernel_size=1))
            if i < len(widths) - 1:
                if normalization == "batch":
                    layers.append(nn.BatchNorm1d(width))
                layers.append(nn.LeakyReLU(POINTNET_NEGATIVE_SLOPE))
            channels = width
        self.layers = nn.Sequential(*layers)

    def forward(self, clouds: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        inputs = clouds[..., :3] / TRANSLATION_UNIT_M
        if self.normals:
            inputs = torch.cat([inputs, clouds[..., 3:6]], dim=-1)
        per_point = self.layers(inputs.transpose(1, 2))  # (C, F, N)
        return per_point.max(dim=2).values, per_point.transpose(1, 2)


def _mlp(in_dim: int, hidden: tuple[int, ...], out_dim: int) -> nn.Sequential:
    layers: list[nn.Module] = []
    for width in hidden:
        layers += [nn.Linear(in_dim, width), nn.ReLU()]
        in_dim = width
    layers.append(nn.Linear(in_dim, out_dim))
    return nn.Sequential(*layers)


class GraspCVAE(nn.Module):
    """PointNet-conditioned VAE over hand poses of one hand.

    Point clouds come once per object (and scale) in a batch; each grasp names its
    cloud (``cloud_index``) and its associated point in that cloud (``point_index``),
    so the PointNet runs once per cloud, not once per grasp. ``hand_record`` ({"hand", "joint_names"[, "hand_sha256"]},
    ``hand.choice.hand_record``; None: the Shadow Hand) sets the pose width: 6 + J stored, 9 + J features.
    """

    def __init__(self, config: ModelConfig, type_vocabulary: tuple[str, ...] = (), hand_record: dict | None = None) -> None:
        super().__init__()
        self.config = config
        self.hand_record = dict(hand_record) if hand_record is not None else shadow_hand_record()
        self.joint_count = len(self.hand_record["joint_names"])
        self.pose_width = STORED_JOINTS_START + self.joint_count  # numbers in a stored pose: 28 for the Shadow Hand
        self.pose_feature_dim = pose_feature_dim(self.joint_count)
        self.type_vocabulary = tuple(type_vocabulary)  # the training grasps' types; () for a model trained before types
        self.type_inputs = len(self.type_vocabulary) if len(self.type_vocabulary) > 1 else 0  # one-hot width
        self.pointnet = PointNet(config.pointnet_widths, config.normalization, config.point_normals)
        self._build_networks(config.condition_dim + config.frame_input_dim + self.type_inputs)
        self._hands: dict[str, object] = {}  # the refiner's hand model per device, built when first needed
        self.refiner = None
        if config.refiner_hidden:
            inputs = self.pose_feature_dim + config.condition_dim + config.frame_input_dim + self.type_inputs
            self.refiner = _mlp(inputs + reading_width(self.refiner_hand(torch.device("cpu"))), config.refiner_hidden, self.pose_feature_dim)
            nn.init.zeros_(self.refiner[-1].weight)  # an untrained refiner returns the decoded pose
            nn.init.zeros_(self.refiner[-1].bias)
        # The training grasps' posterior codes (mu, log sigma^2), stored with the weights after
        # training so that sampling can draw from their aggregate (``latent_codes.sample_latents``).
        self.register_buffer("codes_mu", torch.zeros(0, config.latent_dim))
        self.register_buffer("codes_log_var", torch.zeros(0, config.latent_dim))
        self.register_buffer("codes_condition", torch.zeros(0, config.condition_dim))
        self.register_buffer("codes_cloud", torch.zeros(0, dtype=torch.long))
        self.register_buffer("codes_type", torch.zeros(0, dtype=torch.long))

    def _build_networks(self, inputs: int) -> None:
        """The networks after PointNet, each reading ``inputs`` condition values (``_inputs``): encoder and decoder."""
        self.encoder = _mlp(self.pose_feature_dim + inputs, self.config.encoder_hidden, 2 * self.config.latent_dim)
        self.decoder = _mlp(self.config.latent_dim + inputs, self.config.decoder_hidden, self.pose_feature_dim)

    @property
    def grasp_types(self) -> tuple[str, ...]:
        """The types the model can make (``type_condition.known_types``): its vocabulary, or power."""
        return known_types(self.type_vocabulary)

    def set_latent_codes(
        self, mu: torch.Tensor, log_var: torch.Tensor, condition: torch.Tensor | None = None, cloud: torch.Tensor | None = None,
        grasp_type: torch.Tensor | None = None,
    ) -> None:
        """Store the training grasps' codes (N, latent) each, their conditions (N, 2F: the cloud's global feature and the
        associated point's local feature), which training cloud (object and scale) each grasp is on (N,) and its type's
        column in the vocabulary (N,; None: every code of type 0, as in a model trained before types)."""
        device = self.codes_mu.device
        self.codes_mu = mu.detach().to(device).clone()
        self.codes_log_var = log_var.detach().to(device).clone()
        condition = torch.zeros(0, self.config.condition_dim) if condition is None else condition
        cloud = torch.zeros(0, dtype=torch.long) if cloud is None else cloud
        grasp_type = torch.zeros(len(mu), dtype=torch.long) if grasp_type is None else grasp_type
        self.codes_condition = condition.detach().to(device).clone()
        self.codes_cloud = torch.as_tensor(cloud, dtype=torch.long).to(device).clone()
        self.codes_type = torch.as_tensor(grasp_type, dtype=torch.long).to(device).clone()

    @property
    def latent_codes(self) -> tuple[torch.Tensor, torch.Tensor]:
        return self.codes_mu, self.codes_log_var

    def condition(self, clouds: torch.Tensor, cloud_index: torch.Tensor, point_index: torch.Tensor) -> torch.Tensor:
        """Condition vectors (B, 2F) from clouds (C, N, 3 or 6: xyz in metres, normal) and each grasp's cloud and associated point."""
        return condition_at(self.pointnet(clouds), cloud_index, point_index)

    def pose_anchors(self, anchor: torch.Tensor, pose_features: torch.Tensor) -> torch.Tensor:
        """Anchors (B, 6: point, normal) completed for known poses (B, 9 + J): the ``hand`` frame adds the palm's lateral axis."""
        if self.config.pose_frame != "hand":
            return anchor
        palm_rot, _, _ = features_to_parts(pose_features)
        return torch.cat([anchor[:, :6], palm_rot[:, :, LATERAL_AXIS]], dim=1)

    def sampling_anchors(self, anchor: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """Anchors (B, 6) completed for new grasps: the ``hand`` frame adds a tangent at a uniformly random roll."""
        if self.config.pose_frame != "hand":
            return anchor
        frame = surface_frames(anchor[:, 3:6])
        angle = (torch.rand(len(anchor), generator=generator) * (2 * torch.pi)).to(anchor.device)
        lateral = frame[:, :, 1] * angle.cos()[:, None] + frame[:, :, 2] * angle.sin()[:, None]
        return torch.cat([anchor[:, :6], lateral], dim=1)

    def _frames(self, anchor: torch.Tensor) -> torch.Tensor:
        """Pose frames (B, 3, 3) at anchors: ``surface`` or ``hand`` (x along the normal)."""
        if self.config.pose_frame == "hand":
            if anchor.shape[1] < 9:
                raise ValueError(f"pose_frame 'hand' needs anchors with a lateral axis, (B, 9), got {tuple(anchor.shape)}")
            return tangent_frames(anchor[:, 3:6], anchor[:, 6:9])
        return _anchor_frames(anchor)

    def _inputs(self, condition: torch.Tensor, anchor: torch.Tensor, grasp_type: torch.Tensor | None = None) -> torch.Tensor:
        """Condition plus the frame inputs (for ``hand``, the object's vertical in the pose frame) plus the type's one-hot
        (``grasp_type`` (B,) vocabulary columns; required when the model reads types)."""
        parts = [condition]
        if self.config.pose_frame == "hand":
            parts.append(self._frames(anchor)[:, 2, :])
        if self.type_inputs:
            if grasp_type is None:
                raise ValueError(f"the model is conditioned on grasp types ({', '.join(self.type_vocabulary)}): give each grasp's type")
            parts.append(torch.nn.functional.one_hot(grasp_type.to(condition.device), self.type_inputs).to(condition.dtype))
        return torch.cat(parts, dim=1) if len(parts) > 1 else condition

    def _to_frame(self, pose_features: torch.Tensor, anchor: torch.Tensor) -> torch.Tensor:
        """Object-frame pose features -> the features the networks see (``config.pose_frame``)."""
        if self.config.pose_frame == "object":
            return pose_features
        if self.config.pose_frame == "point":
            return shift_translation(pose_features, -anchor[:, :3])
        inverse = self._frames(anchor).transpose(1, 2)
        palm_rot, palm_t, joints = features_to_parts(pose_features)
        return parts_to_features(inverse @ palm_rot, (inverse @ (palm_t - anchor[:, :3])[..., None])[..., 0], joints)

    def _from_frame(self, features: torch.Tensor, anchor: torch.Tensor) -> torch.Tensor:
        """Inverse of ``_to_frame``: the networks' features -> object-frame pose features."""
        if self.config.pose_frame == "object":
            return features
        if self.config.pose_frame == "point":
            return shift_translation(features, anchor[:, :3])
        frame = self._frames(anchor)
        palm_rot, palm_t, joints = features_to_parts(features)
        return parts_to_features(frame @ palm_rot, anchor[:, :3] + (frame @ palm_t[..., None])[..., 0], joints)

    def encode(
        self, pose_features: torch.Tensor, condition: torch.Tensor, anchor: torch.Tensor, grasp_type: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(mu, log sigma^2), each (B, latent), of poses (B, 9 + J) at ``anchor`` (B, 6: point m, normal; ``pose_anchors``) of
        types ``grasp_type`` (B,; vocabulary columns, for a model that reads types)."""
        inputs = torch.cat([self._to_frame(pose_features, anchor), self._inputs(condition, anchor, grasp_type)], dim=1)
        mu, log_var = self.encoder(inputs).chunk(2, dim=1)
        return mu, log_var.clamp(-20.0, 10.0)

    def decode(
        self, latent: torch.Tensor, condition: torch.Tensor, anchor: torch.Tensor, grasp_type: torch.Tensor | None = None
    ) -> torch.Tensor:
        """Pose features (B, 9 + J) in the object frame for latents (B, latent) under their conditions, anchors and types."""
        return self._from_frame(self.decoder(torch.cat([latent, self._inputs(condition, anchor, grasp_type)], dim=1)), anchor)

    def refiner_hand(self, device: torch.device):
        """The kinematic model of the model's hand on ``device`` (the refiner's reading needs its points)."""
        from dexlite_pipeline.hand.choice import resolve_hand

        key = str(device)
        if key not in self._hands:
            self._hands[key] = resolve_hand(self.hand_record["hand"], device)
        return self._hands[key]

    def refine(
        self, pose_features: torch.Tensor, condition: torch.Tensor, anchor: torch.Tensor, clouds: torch.Tensor,
        cloud_index: torch.Tensor, grasp_type: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """Decoded poses (B, 9 + J, object frame) corrected by the refiner from where their hands land on ``clouds``
        (C, N, 6; grasp b on cloud ``cloud_index[b]``); unchanged for a model without one (``model.refiner``)."""
        if self.refiner is None:
            return pose_features
        hand, inputs = self.refiner_hand(pose_features.device), self._inputs(condition, anchor, grasp_type)
        for _ in range(self.config.refiner_passes):
            reading = surface_reading(hand, pose_features.detach(), clouds, cloud_index)
            start = self._to_frame(pose_features, anchor)
            pose_features = self._from_frame(start + self.refiner(torch.cat([start, inputs, reading], dim=1)), anchor)
        return pose_features

    def generate(
        self, latent: torch.Tensor, condition: torch.Tensor, anchor: torch.Tensor, clouds: torch.Tensor, cloud_index: torch.Tensor,
        grasp_type: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """The model's poses (B, 9 + J, object frame) for latents: decoded, then refined on the clouds they are of."""
        return self.refine(self.decode(latent, condition, anchor, grasp_type), condition, anchor, clouds, cloud_index, grasp_type)

    def forward(
        self, pose_features: torch.Tensor, condition: torch.Tensor, anchor: torch.Tensor, noise: torch.Tensor,
        grasp_type: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Reparameterized pass: (reconstructed features, mu, log sigma^2); ``noise`` ~ N(0, I) given by the caller."""
        mu, log_var = self.encode(pose_features, condition, anchor, grasp_type)
        latent = mu + torch.exp(0.5 * log_var) * noise
        return self.decode(latent, condition, anchor, grasp_type), mu, log_var


def condition_at(cloud_features: tuple[torch.Tensor, torch.Tensor], cloud_index: torch.Tensor, point_index: torch.Tensor) -> torch.Tensor:
    """[global feature of the grasp's cloud, per-point feature of its associated point] from PointNet's output."""
    global_feature, per_point = cloud_features
    return torch.cat([global_feature[cloud_index], per_point[cloud_index, point_index]], dim=1)


def anchor_at(clouds: torch.Tensor, cloud_index: torch.Tensor, point_index: torch.Tensor) -> torch.Tensor:
    """(B, 6) associated points [position in metres, outward normal]: point ``point_index`` of cloud ``cloud_index``."""
    return clouds[cloud_index, point_index, :6]


def _anchor_frames(anchor: torch.Tensor) -> torch.Tensor:
    """Surface frames (B, 3, 3) of anchors [position, normal] (B, 6)."""
    if anchor.shape[1] < 6:
        raise ValueError(f"pose_frame 'surface' needs anchors with normals, (B, 6), got {tuple(anchor.shape)}")
    return surface_frames(anchor[:, 3:6])


def surface_frames(normal: torch.Tensor) -> torch.Tensor:
    """(B, 3, 3) frames with columns x = outward normal, y = horizontal tangent, z = x × y.

    y is perpendicular to the vertical axis, so the frame turns with an object turned
    about it; where the normal is within ~8° of vertical, y is taken perpendicular to
    the object's x axis instead.
    """
    x = torch.nn.functional.normalize(normal, dim=-1)
    vertical = x.new_tensor([0.0, 0.0, 1.0]).expand_as(x)
    reference = torch.where(x[:, 2:3].abs() > 0.99, x.new_tensor([1.0, 0.0, 0.0]).expand_as(x), vertical)
    y = torch.nn.functional.normalize(torch.cross(reference, x, dim=-1), dim=-1)
    return torch.stack([x, y, torch.cross(x, y, dim=-1)], dim=-1)


def tangent_frames(normal: torch.Tensor, lateral: torch.Tensor) -> torch.Tensor:
    """(B, 3, 3) frames with columns x = outward normal, y = ``lateral`` projected onto the tangent plane, z = x × y.

    Where ``lateral`` is within ~8° of the normal (a palm edge-on to the surface), the
    ``surface_frames`` tangent is used instead.
    """
    x = torch.nn.functional.normalize(normal, dim=-1)
    lateral = torch.nn.functional.normalize(lateral, dim=-1)
    fallback = surface_frames(x)[:, :, 1]
    lateral = torch.where((lateral * x).sum(-1, keepdim=True).abs() > 0.99, fallback, lateral)
    y = torch.nn.functional.normalize(lateral - (lateral * x).sum(-1, keepdim=True) * x, dim=-1)
    return torch.stack([x, y, torch.cross(x, y, dim=-1)], dim=-1)


def kl_divergence(mu: torch.Tensor, log_var: torch.Tensor) -> torch.Tensor:
    """KL(N(mu, sigma^2) || N(0, I)) per grasp (B,), summed over latent dimensions."""
    return -0.5 * (1.0 + log_var - mu.pow(2) - log_var.exp()).sum(dim=1)
