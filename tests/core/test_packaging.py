"""A real wheel install registers the built-in plugins; a third-party entry point is found."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _run(cmd: list[str], cwd: Path, env: dict[str, str] | None = None
         ) -> subprocess.CompletedProcess[str]:
    out = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=600,
                         env={**os.environ, **(env or {})})
    assert out.returncode == 0, f"{cmd} failed:\n{out.stdout}\n{out.stderr}"
    return out


@pytest.fixture(scope="module")
def wheel_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Build repbench's wheel and install it (no deps) into a private site directory."""
    tmp = tmp_path_factory.mktemp("wheel")
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-w",
          str(tmp / "dist"), str(ROOT)], cwd=tmp)
    wheel = next((tmp / "dist").glob("repbench-*.whl"))
    site = tmp / "site"
    _run([sys.executable, "-m", "pip", "install", "--no-deps", "--target", str(site),
          str(wheel)], cwd=tmp)
    return site


def test_wheel_install_registers_builtin_plugins(wheel_site: Path, tmp_path: Path) -> None:
    code = textwrap.dedent("""
        import repbench, repbench_encoders, repbench_tasks
        from repbench.registry import encoders, tasks
        print(repbench.__file__); print(repbench_encoders.__file__)
        print(len(encoders.names()), "PegInHole-v0" in tasks)
        print(repbench.load_suite("smoke").name)
        import repbench_encoders.vae, repbench_encoders.baselines, repbench_tasks.peg_in_hole
    """)
    out = _run([sys.executable, "-c", code], cwd=tmp_path,
               env={"PYTHONPATH": str(wheel_site)})
    lines = out.stdout.splitlines()
    assert lines[0].startswith(str(wheel_site)) and lines[1].startswith(str(wheel_site))
    from repbench._toml import loads

    pyproject = loads((ROOT / "pyproject.toml").read_text())
    n_builtin = len(pyproject["project"]["entry-points"]["repbench.encoders"])
    assert lines[2] == f"{n_builtin} True" and lines[3] == "smoke"


_PLUGIN_PYPROJECT = """
[build-system]
requires = ["setuptools>=69"]
build-backend = "setuptools.build_meta"
[project]
name = "rb-ext-plugin"
version = "0.0.1"
[project.entry-points."repbench.encoders"]
mean_pixel = "rb_ext_plugin:MeanPixel"
"""

_PLUGIN_MODULE = '''
import numpy as np
import repbench


class MeanPixel(repbench.Encoder):
    """Mean image colour, from a third-party package."""

    required_modalities = ("image",)

    def __init__(self, scale: float = 1.0):
        self.scale = scale

    def fit(self, dataset):
        self.fitted_ = True
        return self

    def encode(self, observations):
        self.check_is_fitted()
        img = self.check_observations(observations)["image"]
        return (img.reshape(len(img), -1, 3).mean(1) * self.scale).astype(np.float32)

    @property
    def latent_dim(self):
        return 3
'''


def test_third_party_entry_point_is_listed_and_usable(tmp_path: Path) -> None:
    pkg = tmp_path / "plugin"
    pkg.mkdir()
    (pkg / "pyproject.toml").write_text(_PLUGIN_PYPROJECT)
    (pkg / "rb_ext_plugin.py").write_text(_PLUGIN_MODULE)
    site = tmp_path / "site"
    _run([sys.executable, "-m", "pip", "install", "--no-deps", "--no-build-isolation",
          "--target", str(site), str(pkg)], cwd=tmp_path)
    env = {"PYTHONPATH": str(site)}
    out = _run([sys.executable, "-m", "repbench.cli", "list", "encoders"], cwd=tmp_path, env=env)
    assert "mean_pixel" in out.stdout and "from a third-party package" in out.stdout
    code = textwrap.dedent("""
        from repbench.registry import encoders
        from repbench.testing import check_encoder
        from repbench.testing.synthetic import synthetic_dataset
        enc = encoders.get("mean_pixel")(scale=2.0).fit(synthetic_dataset())
        print(enc.encode(synthetic_dataset().obs(slice(0, 5))).shape)
        check_encoder("mean_pixel")
        print("conformant")
    """)
    out = _run([sys.executable, "-c", code], cwd=tmp_path, env=env)
    assert out.stdout.split() == ["(5,", "3)", "conformant"]
