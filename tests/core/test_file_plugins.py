"""Plugins given by reference instead of a registered name: ``path/to/file.py:Class`` and
``module:Class`` (issue 24, item 3). The worker-process path is exercised end to end in
``tests/e2e/test_evaluate.py::test_encoder_in_a_plain_file_evaluated_metrics_only``."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from repbench.errors import PluginError
from repbench.pipeline.plan import build_plan
from repbench.pipeline.suite import Suite, load_suite
from repbench.registry import encoders
from repbench.testing.synthetic import synthetic_dataset
from tests.core.test_packaging import _PLUGIN_MODULE


@pytest.fixture
def plugin_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A working directory holding one encoder file, ``my_encoder.py`` (class MeanPixel)."""
    (tmp_path / "my_encoder.py").write_text(_PLUGIN_MODULE)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_file_reference_resolves_to_the_class_in_the_file(plugin_dir: Path) -> None:
    cls = encoders.get("my_encoder.py:MeanPixel")
    assert cls.__name__ == "MeanPixel" and cls.__doc__.startswith("Mean image colour")
    assert encoders.get(str(plugin_dir / "my_encoder.py") + ":MeanPixel") is cls  # same file
    assert "my_encoder.py:MeanPixel" in encoders.names()
    encoders.unregister("my_encoder.py:MeanPixel")


def test_module_reference_finds_a_module_in_the_working_directory(plugin_dir: Path,
                                                                  monkeypatch: pytest.MonkeyPatch
                                                                  ) -> None:
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", str(plugin_dir))])
    monkeypatch.delitem(sys.modules, "my_encoder", raising=False)
    cls = encoders.get("my_encoder:MeanPixel")
    assert cls.__module__ == "my_encoder"
    encoders.unregister("my_encoder:MeanPixel")


@pytest.mark.parametrize(("spec", "message"), [
    ("missing.py:MeanPixel", r"plugin file 'missing.py' of 'missing.py:MeanPixel' does not exist"),
    ("my_encoder.py:Nope", r"'my_encoder.py' has no attribute 'Nope'"),
    ("collections:OrderedDict", r"rejected: expected a subclass of repbench\.Encoder"),
    ("no_such_module_xyz:Thing", r"cannot import module 'no_such_module_xyz'"),
])
def test_bad_reference_is_one_clear_error_and_is_not_left_registered(
        plugin_dir: Path, spec: str, message: str) -> None:
    with pytest.raises(PluginError, match=message):
        encoders.get(spec)
    assert spec not in encoders.names()


def test_file_that_raises_on_import_names_the_file_and_the_error(plugin_dir: Path) -> None:
    (plugin_dir / "broken.py").write_text("raise RuntimeError('boom')\n")
    with pytest.raises(PluginError, match=r"broken\.py.*failed: RuntimeError: boom"):
        encoders.get("broken.py:Anything")


def test_saved_file_encoder_loads_in_a_fresh_process(plugin_dir: Path) -> None:
    """Encoder.save records the file's absolute path, so a worker (any working directory)
    loads it."""
    enc = encoders.get("my_encoder.py:MeanPixel")(scale=2.0).fit(synthetic_dataset())
    enc.save(plugin_dir / "enc.pt")
    obs = synthetic_dataset().observations
    expected = enc.encode(obs)
    np.save(plugin_dir / "expected.npy", expected)
    code = ("import numpy as np, repbench; from repbench.testing.synthetic import "
            "synthetic_dataset; e = repbench.Encoder.load('enc.pt'); "
            "z = e.encode(synthetic_dataset().observations); "
            "assert np.array_equal(z, np.load('expected.npy')), 'latents differ'; "
            "print(type(e).__name__, e.scale)")
    (plugin_dir / "elsewhere").mkdir()
    for name in ("enc.pt", "expected.npy"):
        (plugin_dir / "elsewhere" / name).write_bytes((plugin_dir / name).read_bytes())
    proc = subprocess.run([sys.executable, "-c", code], cwd=plugin_dir / "elsewhere",
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split() == ["MeanPixel", "2.0"]
    encoders.unregister("my_encoder.py:MeanPixel")


def test_editing_the_file_changes_the_encoder_stage_key(plugin_dir: Path) -> None:
    """Stage keys carry the file's digest: an edited encoder is recomputed, not reused."""
    smoke = load_suite("smoke").model_dump()
    smoke["encoders"] = ["my_encoder.py:MeanPixel", "pca"]
    smoke.pop("encoder_params", None)

    def keys() -> dict[str, str]:
        plan = build_plan(Suite.model_validate(smoke))
        return {s.label: s.key for s in plan.stages() if " encoder " in s.label}

    before = keys()
    # the same class in a changed file: a new module object in a fresh process; here, drop the
    # cached module so the edit is read, as a new run would
    for name in [m for m in sys.modules if m.startswith("repbench_file_my_encoder")]:
        del sys.modules[name]
    encoders.unregister("my_encoder.py:MeanPixel")
    (plugin_dir / "my_encoder.py").write_text(_PLUGIN_MODULE.replace("* self.scale",
                                                                     "* self.scale * 2"))
    after = keys()
    file_stage = next(k for k in before if "MeanPixel" in k)
    pca_stage = next(k for k in before if "pca" in k)
    assert before[file_stage] != after[file_stage]
    assert before[pca_stage] == after[pca_stage]
    encoders.unregister("my_encoder.py:MeanPixel")
