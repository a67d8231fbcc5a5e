"""The reconstruction figure (paper appendix)."""

from __future__ import annotations

import matplotlib.image as mpimg
import pytest

import repbench
from repbench.dataset import Dataset
from repbench.errors import DataError
from repbench_encoders.figures import save_reconstruction_figure


@pytest.mark.parametrize("name", ["vae_lowkl", "pred_im_lowkl"])
def test_reconstruction_figure(name: str, tiny_dataset: Dataset, tmp_path) -> None:
    enc = repbench.encoders.get(name)(epochs=1, batch_size=8, progress=False).fit(tiny_dataset)
    path = save_reconstruction_figure(enc, tiny_dataset, tmp_path / "fig" / "r.png", n=5)
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[0] > 300 and img.shape[1] > 400


def test_reconstruction_figure_needs_a_decoder(tiny_dataset: Dataset, tmp_path) -> None:
    enc = repbench.encoders.get("pca")(latent_dim=3).fit(tiny_dataset)
    with pytest.raises(DataError, match="needs a VAE-family encoder"):
        save_reconstruction_figure(enc, tiny_dataset, tmp_path / "r.png")
