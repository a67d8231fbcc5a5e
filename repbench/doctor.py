"""``repbench doctor``: is this machine ready to run repbench, and if not, what to fix."""

from __future__ import annotations

import os
import platform
from collections.abc import Callable

_TINY_SCENE = """
<mujoco>
  <worldbody>
    <light pos="0 0 3"/>
    <camera name="cam" pos="0 0 1.5" xyaxes="1 0 0 0 1 0"/>
    <geom type="plane" size="1 1 .1" rgba=".2 .3 .4 1"/>
    <geom type="box" size=".2 .2 .2" pos="0 0 .2" rgba=".9 .1 .1 1"/>
  </worldbody>
</mujoco>
"""


def check_render(size: int = 64) -> tuple[bool, str]:
    """Render a tiny MuJoCo scene offscreen; (ok, message)."""
    import numpy as np

    try:
        import mujoco

        model = mujoco.MjModel.from_xml_string(_TINY_SCENE)
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        with mujoco.Renderer(model, size, size) as renderer:
            renderer.update_scene(data, camera="cam")
            image = renderer.render()
    except Exception as exc:  # any backend failure is reported, not raised
        return False, f"offscreen render failed ({type(exc).__name__}: {exc})"
    if image.shape != (size, size, 3) or int(np.ptp(image)) == 0:
        return False, f"offscreen render returned a blank or malformed image {image.shape}"
    return True, f"{size}x{size} offscreen render ok (mean pixel {image.mean():.1f})"


#: The Debian/Ubuntu packages headless rendering needs, and the browser the page test drives.
RENDER_PACKAGES = ("libegl1", "libgl1", "libgl1-mesa-dri")
BROWSER_PACKAGE = "chromium"


def render_fix() -> str:
    """What to do when MuJoCo cannot render offscreen (:func:`check_render` failed)."""
    return ("headless rendering needs EGL (Debian/Ubuntu): "
            f"{apt_install_line(RENDER_PACKAGES)}; and MUJOCO_GL=egl")


def apt_install_line(packages: tuple[str, ...] | list[str], *, is_root: bool | None = None,
                     sudo: str | None = None) -> str:
    """The exact command that installs ``packages`` here: plain ``apt-get`` as root, through
    sudo otherwise (``apt-get update`` first, which a fresh machine needs)."""
    import shutil

    root = (os.geteuid() == 0) if is_root is None and hasattr(os, "geteuid") else bool(is_root)
    prefix = "" if root else ((sudo if sudo is not None else shutil.which("sudo") or "sudo")
                              .rsplit("/", 1)[-1] + " ")
    return (f"{prefix}apt-get update && {prefix}apt-get install -y "
            f"{' '.join(packages)}")


def run_doctor(echo: Callable[[str], None] = print) -> bool:
    """Print a report; return True when everything needed works."""
    from importlib.metadata import PackageNotFoundError, version

    ok = True
    fixes: list[str] = []
    echo(f"python      {platform.python_version()} ({platform.machine()}, {os.cpu_count()} CPUs)")
    for dist in ("repbench", "torch", "mujoco", "robosuite", "stable-baselines3", "gymnasium",
                 "numpy", "scikit-learn", "ray"):
        try:
            echo(f"{dist:<11} {version(dist)}")
        except PackageNotFoundError:
            echo(f"{dist:<11} not installed")
            if dist == "ray":
                continue
            ok = False
            fixes.append(f"pip install {dist}")
    try:
        mj = tuple(int(x) for x in version("mujoco").split(".")[:2])
        if mj >= (3, 10):
            ok = False
            fixes.append("pip install 'mujoco>=3.3,<3.10' (robosuite 1.5.2 breaks with >= 3.10)")
    except PackageNotFoundError:
        pass
    backend = os.environ.get("MUJOCO_GL", "(MuJoCo default)")
    echo(f"rendering   MUJOCO_GL={backend} DISPLAY={os.environ.get('DISPLAY', '')!r}")
    render_ok, msg = check_render()
    echo(f"render      {msg}")
    if not render_ok:
        ok = False
        fixes.append(render_fix())
    import shutil

    browser = shutil.which(BROWSER_PACKAGE)
    echo(f"browser     {browser or 'chromium not found (only the HTML page test needs it)'}")
    if browser is None:  # optional: only the browser test of the page uses it
        fixes.append(f"(optional, for the page test) {apt_install_line([BROWSER_PACKAGE])}")
    try:
        import torch

        if torch.cuda.is_available():
            echo(f"device      CUDA: {torch.cuda.get_device_name(0)}")
        else:
            echo(f"device      CPU only ({torch.get_num_threads()} torch threads); "
                 "the quick suite is sized for this")
    except ImportError:
        pass
    if fixes:
        echo("to fix:")
        for f in fixes:
            echo(f"  - {f}")
    echo("all good" if ok else "problems found")
    return ok
