"""The paper's multimodal VAE network (§IV and appendix "Encoder").

Encoder: an image conv stack growing from 32 to 128 filters (kernel 4, strides 2, 2, 2, 1,
ReLU); force/torque and proprioception MLPs with one hidden layer of 16; a fusion layer of 64
units fully connected to the mean and log standard deviation of z.

Decoder: inverts the stack. From ``z ⊕ torque input`` (the last action) a 64-unit layer feeds an
image branch (FC to the conv feature map, then transposed convolutions mirroring the encoder)
and a force branch (hidden layer of 16).

Auxiliary heads (built only when their loss weight is non-zero):

* success classifier: 2 FC layers (64 hidden) then softmax over {fail, success};
* next-latent predictor: ``z_n ⊕ a_n`` → 64 hidden (ReLU) → mean and log-std of ``z_{n+1}``;
* next-image predictor: ``z_n ⊕ a_n`` → an extra FC layer (64) → the decoder's image branch.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn

#: Log-std is clamped into this range for numerical safety (σ from 4.5e-5 to 7.4).
LOG_STD_MIN, LOG_STD_MAX = -10.0, 2.0


@dataclass(frozen=True)
class NetworkSpec:
    """Everything needed to rebuild the network (stored with the weights)."""

    image_size: int
    """Height = width of the input image (a multiple of 8, at least 32)."""
    ft_dim: int
    """Force/torque input size (6)."""
    proprio_dim: int
    """Proprioception input size P."""
    action_dim: int
    """Torque/action input size A, given to the decoder and the predictors."""
    latent_dim: int
    """Latent size D."""
    conv_channels: tuple[int, ...] = (32, 64, 128, 128)
    """Filters of the conv stack (paper: from 32 to 128)."""
    conv_strides: tuple[int, ...] = (2, 2, 2, 1)
    """Strides of the conv stack (paper: 2/1). Stride-2 layers halve the size (padding 1)."""
    kernel_size: int = 4
    """Kernel size of every conv layer (paper: 4)."""
    modality_hidden: int = 16
    """Hidden (and output) size of the force and proprioception MLPs (paper: 16)."""
    fusion_hidden: int = 64
    """Fusion layer size (paper: 64)."""
    modalities: tuple[str, ...] = ("image", "ft", "proprio")
    """Input modalities the encoder reads (per-modality ablations read fewer)."""
    decoder: bool = True
    """Build the image/force decoder (VAE family); contrastive and supervised encoders do not."""
    success_head: bool = False
    pred_z_head: bool = False
    pred_im_head: bool = False

    def to_dict(self) -> dict[str, object]:
        d = asdict(self)
        d["conv_channels"] = list(self.conv_channels)
        d["conv_strides"] = list(self.conv_strides)
        d["modalities"] = list(self.modalities)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, object]) -> NetworkSpec:
        d = dict(d)
        d["conv_channels"] = tuple(d["conv_channels"])  # type: ignore[arg-type]
        d["conv_strides"] = tuple(d["conv_strides"])  # type: ignore[arg-type]
        if "modalities" in d:  # absent in files written before the per-modality ablations
            d["modalities"] = tuple(d["modalities"])  # type: ignore[arg-type]
        return cls(**d)  # type: ignore[arg-type]


def _conv_out(size: int, stride: int, kernel: int) -> int:
    pad = 1 if stride == 2 else 0
    return (size + 2 * pad - kernel) // stride + 1


def feature_map_size(spec: NetworkSpec) -> int:
    """Side length of the last conv feature map."""
    size = spec.image_size
    for s in spec.conv_strides:
        size = _conv_out(size, s, spec.kernel_size)
    return size


def _mlp(n_in: int, hidden: int, n_out: int, out_relu: bool = False) -> nn.Sequential:
    layers: list[nn.Module] = [nn.Linear(n_in, hidden), nn.ReLU(), nn.Linear(hidden, n_out)]
    if out_relu:
        layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class ImageEncoder(nn.Module):
    """Conv stack: image [B, 3, H, W] (normalized) → flat features."""

    def __init__(self, spec: NetworkSpec) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        c_in = 3
        for c, s in zip(spec.conv_channels, spec.conv_strides, strict=True):
            layers += [nn.Conv2d(c_in, c, spec.kernel_size, stride=s, padding=1 if s == 2 else 0),
                       nn.ReLU()]
            c_in = c
        self.net = nn.Sequential(*layers, nn.Flatten())

    def forward(self, image: torch.Tensor) -> torch.Tensor:
        return self.net(image)


class ImageDecoder(nn.Module):
    """Inverse conv stack: a 64-unit hidden vector → image [B, 3, H, W] in [0, 1] scale."""

    def __init__(self, spec: NetworkSpec) -> None:
        super().__init__()
        self.channels = spec.conv_channels[-1]
        self.side = feature_map_size(spec)
        self.fc = nn.Sequential(
            nn.Linear(spec.fusion_hidden, self.channels * self.side * self.side), nn.ReLU()
        )
        layers: list[nn.Module] = []
        chans = list(spec.conv_channels)
        outs = [*chans[:-1][::-1], 3]
        for i, (c_in, c_out, s) in enumerate(
            zip(chans[::-1], outs, spec.conv_strides[::-1], strict=True)
        ):
            layers.append(nn.ConvTranspose2d(c_in, c_out, spec.kernel_size, stride=s,
                                             padding=1 if s == 2 else 0))
            if i < len(chans) - 1:
                layers.append(nn.ReLU())
        self.deconv = nn.Sequential(*layers)

    def forward(self, hidden: torch.Tensor) -> torch.Tensor:
        h = self.fc(hidden).view(-1, self.channels, self.side, self.side)
        return self.deconv(h)


class MultimodalVAENet(nn.Module):
    """The full network: encoder (the branches of ``spec.modalities``), decoder (when
    ``spec.decoder``) and the optional auxiliary heads."""

    def __init__(self, spec: NetworkSpec) -> None:
        super().__init__()
        self.spec = spec
        side = feature_map_size(spec)
        n_img = spec.conv_channels[-1] * side * side
        h, d, a = spec.modality_hidden, spec.latent_dim, spec.action_dim
        unknown = set(spec.modalities) - {"image", "ft", "proprio"}
        if unknown or not spec.modalities:
            raise ValueError(f"modalities must be a non-empty subset of image, ft, proprio; "
                             f"got {spec.modalities}")
        # branches are built in a fixed order, so a full-input network initializes exactly as
        # before the per-modality option existed
        self.image_enc = ImageEncoder(spec) if "image" in spec.modalities else None
        self.ft_enc = _mlp(spec.ft_dim, h, h, out_relu=True) if "ft" in spec.modalities else None
        self.proprio_enc = (_mlp(spec.proprio_dim, h, h, out_relu=True)
                            if "proprio" in spec.modalities else None)
        n_in = ((n_img if self.image_enc is not None else 0)
                + (h if self.ft_enc is not None else 0)
                + (h if self.proprio_enc is not None else 0))
        self.fusion = _mlp(n_in, spec.fusion_hidden, 2 * d)
        # decoder
        self.dec_hidden = self.image_dec = self.ft_dec = None
        if spec.decoder:
            self.dec_hidden = nn.Sequential(nn.Linear(d + a, spec.fusion_hidden), nn.ReLU())
            self.image_dec = ImageDecoder(spec)
            self.ft_dec = _mlp(spec.fusion_hidden, h, spec.ft_dim)
        # auxiliary heads
        self.success_head = _mlp(d, spec.fusion_hidden, 2) if spec.success_head else None
        self.pred_z_head = _mlp(d + a, spec.fusion_hidden, 2 * d) if spec.pred_z_head else None
        self.pred_im_fc = (
            nn.Sequential(nn.Linear(d + a, spec.fusion_hidden), nn.ReLU())
            if spec.pred_im_head else None
        )

    def encode(self, image: torch.Tensor | None, ft: torch.Tensor | None,
               proprio: torch.Tensor | None) -> tuple[torch.Tensor, torch.Tensor]:
        """Normalized inputs → (μ_z, log σ_z). Inputs of modalities the network does not read
        are ignored (pass None)."""
        parts = [branch(x) for branch, x in ((self.image_enc, image), (self.ft_enc, ft),
                                             (self.proprio_enc, proprio)) if branch is not None]
        feats = torch.cat(parts, 1)
        mu, log_std = self.fusion(feats).chunk(2, dim=1)
        return mu, log_std.clamp(LOG_STD_MIN, LOG_STD_MAX)

    def decode(self, z: torch.Tensor, action: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``z ⊕ torque input`` → (image in [0, 1] scale, standardized force)."""
        assert self.dec_hidden is not None and self.image_dec is not None
        assert self.ft_dec is not None
        hidden = self.dec_hidden(torch.cat([z, action], 1))
        return self.image_dec(hidden), self.ft_dec(hidden)

    def predict_next_latent(self, z: torch.Tensor, action: torch.Tensor
                            ) -> tuple[torch.Tensor, torch.Tensor]:
        """(mean, log-std) of z_{n+1} given z_n and a_n."""
        assert self.pred_z_head is not None
        mu, log_std = self.pred_z_head(torch.cat([z, action], 1)).chunk(2, dim=1)
        return mu, log_std.clamp(LOG_STD_MIN, LOG_STD_MAX)

    def predict_next_image(self, z: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        """Image at n+1 from z_n and a_n: an extra FC layer, then the decoder's image branch."""
        assert self.pred_im_fc is not None and self.image_dec is not None
        return self.image_dec(self.pred_im_fc(torch.cat([z, action], 1)))

    def success_logits(self, z: torch.Tensor) -> torch.Tensor:
        assert self.success_head is not None
        return self.success_head(z)
