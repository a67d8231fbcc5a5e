"""Training to convergence: early stopping on a held-out loss, and the per-epoch history.

Every trained encoder here (the VAE family, the contrastive and the supervised encoders) runs the
same loop (:meth:`repbench_encoders.trunk.TrunkEncoder.fit`): at most ``epochs`` passes over the
training episodes; after each, the loss terms on held-out *episodes* (whole episodes, so that
neighbouring steps never sit on both sides); training stops once the held-out total has not
improved by more than ``tol`` (relative) for ``patience`` epochs, and the weights of the best
held-out epoch are restored.

The history (:attr:`TrunkEncoder.history_`) is one dict per epoch::

    {"epoch": 1, "train": {"loss": ..., "recon": ...}, "heldout": {"loss": ..., "recon": ...}}

``train`` averages the minibatch terms seen during the epoch (training mode: sampled z,
augmentations); ``heldout`` is computed after the epoch in evaluation mode (z = μ, fixed
augmentation seed), so curves of one encoder are comparable from epoch to epoch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["EarlyStopping"]


@dataclass
class EarlyStopping:
    """Stop when a monitored loss has not improved for ``patience`` consecutive epochs.

    An epoch improves on the best so far when ``value < best - tol * |best|``; ``patience=0``
    never stops. Non-finite values never improve.

    Example::

        stopper = EarlyStopping(patience=3)
        for epoch in range(1, max_epochs + 1):
            ...
            if stopper.update(epoch, heldout_loss):
                break
        best_epoch = stopper.best_epoch
    """

    patience: int
    """Epochs without improvement before stopping (0: never stop)."""
    tol: float = 1e-3
    """Relative improvement that counts (0.001 = 0.1 % of the best loss)."""
    best: float = field(default=math.inf, init=False)
    """Best value seen so far."""
    best_epoch: int = field(default=0, init=False)
    """Epoch (1-based) of the best value; 0 before the first finite value."""
    bad_epochs: int = field(default=0, init=False)
    """Consecutive epochs without improvement."""

    def update(self, epoch: int, value: float) -> bool:
        """Record ``value`` for ``epoch``; return True when training should stop now."""
        if math.isfinite(value) and (
                not math.isfinite(self.best) or value < self.best - self.tol * abs(self.best)):
            self.best, self.best_epoch, self.bad_epochs = value, epoch, 0
            return False
        self.bad_epochs += 1
        return self.patience > 0 and self.bad_epochs >= self.patience

    @property
    def improved(self) -> bool:
        """Whether the last update was a new best."""
        return self.bad_epochs == 0 and self.best_epoch > 0
