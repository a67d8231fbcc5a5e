"""Device and thread settings, in one place for encoders, metrics, agents and executors.

* :func:`resolve_device` — ``"auto"`` → ``"cuda"`` when torch sees a GPU, else ``"cpu"``; any
  other value is checked to be a torch device and returned unchanged.
* :func:`exact_cuda` — on a CUDA device, deterministic kernels and full float32 (no TF32) inside
  the block, so a seeded training gives the same weights run to run; on the CPU a no-op.
* :func:`jax_single_thread` — JAX (the SBX agents) on one CPU thread, set before it is imported.
* :func:`torch_threads` — inside the block torch (and, with ``blas=True``, the BLAS/OpenMP pools
  of numpy and scikit-learn) use ``n`` threads; the previous settings come back afterwards.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from repbench.errors import ConfigError


def resolve_device(device: str) -> str:
    """``"auto"`` → ``"cuda"`` if torch sees a GPU, else ``"cpu"``; ``"cpu"``, ``"cuda"``,
    ``"cuda:1"`` ... unchanged; anything torch does not know raises ConfigError."""
    import torch

    if device == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    try:
        torch.device(device)
    except (RuntimeError, TypeError) as exc:
        raise ConfigError(f"device {device!r} is not a torch device ({exc}); use 'auto', "
                          "'cpu' or 'cuda'") from None
    return device


@contextlib.contextmanager
def torch_threads(n: int | None, *, blas: bool = False) -> Iterator[None]:
    """Use ``n`` torch intra-op threads inside the block (``None``: leave settings alone).

    ``blas=True`` also limits the BLAS/OpenMP thread pools (threadpoolctl), as every executor
    does around a stage (:data:`repbench.pipeline.stages.STAGE_THREADS`): workers then do not
    oversubscribe the cores, and every executor sums in the same order, so deterministic stages
    give bit-identical results everywhere. threadpoolctl only reaches libraries already loaded,
    so the ones repbench's stages use (numpy's and scipy's BLAS, scikit-learn's and torch's
    OpenMP) are loaded first: a library loaded inside the block would keep its default.
    """
    if n is None:
        yield
        return
    import torch

    if blas:
        _load_thread_pools()

    before = torch.get_num_threads()
    torch.set_num_threads(int(n))
    try:
        if blas:
            from threadpoolctl import threadpool_limits

            with threadpool_limits(limits=int(n)):
                yield
        else:
            yield
    finally:
        torch.set_num_threads(before)


@contextlib.contextmanager
def exact_cuda(device: str | object) -> Iterator[None]:
    """On a CUDA ``device``: deterministic cuDNN and cuBLAS kernels, no cuDNN autotuning and no
    TF32 inside the block, the previous settings back afterwards; elsewhere nothing changes.

    torch's defaults on a GPU are neither: cuDNN picks nondeterministic convolution kernels (a
    seeded encoder training gives other weights on every run) and computes convolutions in TF32
    (10-bit mantissa; a loss differs from the CPU's in the 4th digit). Measured on an H200,
    torch 2.11: both tests of that (tests/encoders/test_vae.py) fail without this block.
    """
    import os

    import torch

    if torch.device(str(device)).type != "cuda":
        yield
        return
    # read when cuBLAS creates its workspace: deterministic matrix products need it set
    os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
    cudnn, matmul = torch.backends.cudnn, torch.backends.cuda.matmul
    before = (cudnn.deterministic, cudnn.benchmark, cudnn.allow_tf32, matmul.allow_tf32,
              torch.are_deterministic_algorithms_enabled(),
              torch.is_deterministic_algorithms_warn_only_enabled())
    cudnn.deterministic, cudnn.benchmark, cudnn.allow_tf32, matmul.allow_tf32 = (
        True, False, False, False)
    torch.use_deterministic_algorithms(True, warn_only=True)
    try:
        yield
    finally:
        cudnn.deterministic, cudnn.benchmark, cudnn.allow_tf32, matmul.allow_tf32 = before[:4]
        torch.use_deterministic_algorithms(before[4], warn_only=before[5])


def _load_thread_pools() -> None:
    """Import the native libraries with their own thread pools (see :func:`torch_threads`)."""
    import importlib

    for module in ("numpy", "scipy.linalg", "sklearn.utils._openmp_helpers"):
        with contextlib.suppress(ImportError):
            importlib.import_module(module)


#: XLA flags that keep JAX's CPU computations on one thread (the SBX agents' ``torch_threads=1``).
JAX_SINGLE_THREAD_FLAGS = "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"


def jax_single_thread() -> bool:
    """Make JAX (imported after this call) compute on one CPU thread, as the torch stages do.

    XLA reads its flags once, when JAX starts: returns False (and changes nothing) when JAX is
    already imported in this process, True when the flags are set for it.
    """
    import os
    import sys

    if "jax" in sys.modules:
        return False
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_cpu_multi_thread_eigen" not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} {JAX_SINGLE_THREAD_FLAGS}".strip()
    return True
