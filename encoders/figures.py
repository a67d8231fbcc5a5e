"""The paper's appendix figure: samples at n, their reconstructions, successors at n+1 and
their reconstructions (or, for ``pred_im`` encoders, their predictions from z_n and a_n)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from repbench.dataset import IMAGE, Dataset
from repbench.errors import DataError
from repbench_encoders.vae import MultimodalVAE


def save_reconstruction_figure(encoder: MultimodalVAE, dataset: Dataset,
                               path: str | os.PathLike[str], n: int = 8) -> Path:
    """Save a PNG grid of ``n`` pairs (n, n+1) spread over ``dataset``; return its path.

    Rows: samples at n; their reconstructions from μ_z ⊕ last action; successor samples at
    n+1 (same episode); the successors' reconstructions, or their predictions from (z_n, a_n)
    when the encoder has a next-image predictor.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    from repbench.report.figures import save_figure

    if not isinstance(encoder, MultimodalVAE):
        raise DataError(f"save_reconstruction_figure needs a VAE-family encoder with a decoder, "
                        f"got {type(encoder).__name__}")
    encoder.check_is_fitted()
    first, second = dataset.successor_index()
    if first.size == 0:
        raise DataError("save_reconstruction_figure needs pairs (n, n+1) from one episode; "
                        "the dataset has none")
    n = max(1, min(n, first.size))
    pick = np.linspace(0, first.size - 1, n).round().astype(int)
    i, j = first[pick], second[pick]
    obs_i, obs_j = dataset.obs(i), dataset.obs(j)
    recon_i = encoder.reconstruct(obs_i)[IMAGE]
    if encoder.net_.pred_im_fc is not None:
        last_row = encoder.predict_next_image(obs_i, dataset.action[i])
        last_label = "predicted n+1\nfrom (z_n, a_n)"
    else:
        last_row = encoder.reconstruct(obs_j)[IMAGE]
        last_label = "reconstructed\nn+1"
    rows = [(obs_i[IMAGE], "samples at n"), (recon_i, "reconstructed n"),
            (obs_j[IMAGE], "successors n+1"), (last_row, last_label)]

    fig, axes = plt.subplots(4, n, figsize=(1.3 * n + 1.2, 5.6), squeeze=False)
    for r, (images, label) in enumerate(rows):
        for c in range(n):
            ax = axes[r, c]
            ax.imshow(images[c], interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(f"ep {dataset.episode[i[c]]}, n={dataset.step[i[c]]}", fontsize=7)
        axes[r, 0].set_ylabel(label, fontsize=8)
    fig.suptitle(f"{type(encoder).__name__} (latent {encoder.latent_dim}): reconstructions",
                 fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path, dpi=100, tight=False)
