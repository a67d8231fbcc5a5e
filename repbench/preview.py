"""A contact sheet of wrist images from one rollout, with the force magnitude beside each frame.

Generic over any :class:`~repbench.Task`: it collects one ``random`` episode (backwards
exploration for peg-in-hole) and lays out evenly spaced frames with matplotlib.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from repbench.dataset import FT, IMAGE
from repbench.errors import ConfigError
from repbench.pipeline.preflight import check_out_file
from repbench.task import Task


def render_preview(task: Task, out: str | Path, *, n_frames: int = 24, seed: int = 0,
                   steps: int | None = None) -> Path:
    """Roll out one random episode of ``task`` and save a contact sheet PNG to ``out``.

    Each tile shows the wrist image and, beside it, a bar with the force magnitude ``|F|``
    (N) of that step; the title gives the step index. Returns the written path.

    Raises:
        ConfigError: before the rollout, for ``n_frames < 1``, a negative ``seed``, or an
            ``out`` that cannot be written (a folder, an unwritable place, an unknown format).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from repbench.report.figures import save_figure

    _check_preview_args(out, n_frames, seed, steps)
    steps = steps or max(n_frames * 4, 40)
    ds = task.collect("random", n_episodes=1, steps_per_episode=steps, seed=seed,
                      progress=False)
    idx = np.linspace(0, len(ds) - 1, n_frames).round().astype(int)
    images = ds.observations[IMAGE][idx]
    force = np.linalg.norm(ds.observations[FT][:, :3], axis=1)
    fmax = max(float(force.max()), 1.0)
    cols = min(6, n_frames)
    rows = int(np.ceil(n_frames / cols))
    fig, axes = plt.subplots(rows, 2 * cols, figsize=(2.2 * cols, 2.1 * rows),
                             gridspec_kw={"width_ratios": [5, 1] * cols})
    axes = np.atleast_2d(axes)
    for k in range(rows * cols):
        ax_img, ax_f = axes[k // cols, 2 * (k % cols)], axes[k // cols, 2 * (k % cols) + 1]
        ax_img.axis("off")
        if k >= n_frames:
            ax_f.axis("off")
            continue
        i = idx[k]
        ax_img.imshow(images[k])
        ax_img.set_title(f"step {int(ds.step[i])}" + (" ✓" if ds.success[i] else ""), fontsize=8)
        ax_f.bar([0], [force[i]], color="tab:red" if force[i] > 5 else "tab:gray")
        ax_f.set_ylim(0, fmax)
        ax_f.set_xticks([])
        ax_f.tick_params(labelsize=6)
        ax_f.set_title(f"{force[i]:.0f} N", fontsize=7)
    share = ds.metadata.get("contact_share")
    fig.suptitle(f"{task.task_id}: wrist images, |F| beside each frame (seed {seed}"
                 + (f", contact share {share:.0%})" if share is not None else ")"), fontsize=9)
    fig.tight_layout()
    return save_figure(fig, out, tight=False)


def _check_preview_args(out: str | Path, n_frames: int, seed: int, steps: int | None) -> None:
    """One-line ConfigErrors naming the option (as the CLI spells it) and the fix."""
    def integer(v: object) -> bool:
        return isinstance(v, (int, np.integer)) and not isinstance(v, bool)

    if not integer(n_frames) or n_frames < 1:
        raise ConfigError(f"--frames must be a whole number >= 1, got {n_frames!r}")
    if not integer(seed) or seed < 0:
        raise ConfigError(f"--seed must be a whole number >= 0, got {seed!r}")
    if steps is not None and (not integer(steps) or steps < 1):
        raise ConfigError(f"preview steps must be a whole number >= 1, got {steps!r}")
    check_out_file(out)
