"""A contact sheet of wrist images from one rollout, with the force magnitude beside each frame.

Generic over any :class:`~repbench.Task`: it collects one ``random`` episode (backwards
exploration for peg-in-hole) and lays out evenly spaced frames with matplotlib.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from repbench.dataset import FT, IMAGE
from repbench.errors import ConfigError, RepbenchError
from repbench.pipeline.preflight import check_out_file
from repbench.task import Task

#: Most frames a contact sheet takes (``--frames``): 200 tiles are 34 rows of 6, a page of
#: about 13 x 71 inches that matplotlib lays out in tens of seconds; beyond that the sheet is
#: no longer something to look at, and 100000000 (a typo) meant a rollout of 400 million steps.
MAX_PREVIEW_FRAMES = 200


def render_preview(task: Task, out: str | Path, *, n_frames: int = 24, seed: int = 0,
                   steps: int | None = None) -> Path:
    """Roll out one random episode of ``task`` and save a contact sheet PNG to ``out``.

    Each tile shows the wrist image and, beside it, a bar with the force magnitude ``|F|``
    (N) of that step; the title gives the step index. Returns the written path.

    Raises:
        ConfigError: before the rollout, for ``n_frames`` outside ``[1,``
            :data:`MAX_PREVIEW_FRAMES` ``]``, a negative ``seed``, or an ``out`` that cannot be
            written (a folder, an unwritable place, an unknown format); after it, when the
            rollout failed because MuJoCo cannot render here (e.g. a bad ``MUJOCO_GL``), with
            the fix ``repbench doctor`` gives.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from repbench.report.figures import save_figure

    out = _check_preview_args(out, n_frames, seed, steps)
    steps = steps or max(n_frames * 4, 40)
    try:
        ds = task.collect("random", n_episodes=1, steps_per_episode=steps, seed=seed,
                          progress=False)
    except RepbenchError:
        raise
    except Exception as exc:
        _explain_render_failure(task, exc)
        raise
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


def _check_preview_args(out: str | Path, n_frames: int, seed: int, steps: int | None) -> Path:
    """One-line ConfigErrors naming the option (as the CLI spells it) and the fix; returns the
    file that will be written: ``out``, with ``.png`` added when it has no extension (what
    matplotlib does)."""
    def integer(v: object) -> bool:
        return isinstance(v, (int, np.integer)) and not isinstance(v, bool)

    if not integer(n_frames) or n_frames < 1:
        raise ConfigError(f"--frames must be a whole number >= 1, got {n_frames!r}")
    if n_frames > MAX_PREVIEW_FRAMES:
        raise ConfigError(f"--frames must be a whole number in [1, {MAX_PREVIEW_FRAMES}], got "
                          f"{n_frames!r}; a contact sheet of more frames is no longer readable")
    if not integer(seed) or seed < 0:
        raise ConfigError(f"--seed must be a whole number >= 0, got {seed!r}")
    if steps is not None and (not integer(steps) or steps < 1):
        raise ConfigError(f"preview steps must be a whole number >= 1, got {steps!r}")
    path = Path(out).expanduser()
    if str(out).strip() and not path.suffix and not path.is_dir():  # matplotlib adds .png
        out = f"{out}.png"
    return check_out_file(out)


def _explain_render_failure(task: Task, exc: Exception) -> None:
    """Raise a one-line ConfigError when ``exc`` (from the rollout) came from MuJoCo being
    unable to render here: the same check and fix ``repbench doctor`` prints. Returns when
    rendering works (``exc`` is something else)."""
    from repbench.doctor import check_render, render_fix

    ok, message = check_render()
    if not ok:
        raise ConfigError(f"cannot render {task.task_id}'s camera: {message}; {render_fix()}; "
                          "`repbench doctor` checks the installation") from None
