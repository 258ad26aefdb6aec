"""The innovation statistics the adaptive filters compare with their theoretical ones
(SEEDS 1.6): the last N innovations, no mean removal. Two different statistics, two names:

* InnovationCovarianceWindow: the sample second-moment MATRIX of the last N FULL innovation
  vectors, C_hat = (1/N) sum nu nu' (ANKF1 / ANKF2; may carry a batch of filters);
* InnovationVarianceWindow: per measurement row, the mean square of that row's last N
  innovations, Sr_jj = (1/N) sum nu_j^2; a missing cell adds nothing to its row, so the rows
  fill at their own pace (fuzzy-r / fuzzy-q).
"""

from __future__ import annotations

import numpy as np


class InnovationCovarianceWindow:
    """Ring buffer of the last `size` full innovation vectors; `covariance()` is C_hat.

    `shape` is the shape of one innovation, (m,) for one filter or (..., m) for a stack of
    filters stepped together."""

    def __init__(self, size: int, shape: int | tuple[int, ...]) -> None:
        if size < 1:
            raise ValueError(f"innovation window size must be >= 1 (got {size})")
        shape = (shape,) if isinstance(shape, (int, np.integer)) else tuple(shape)
        self.size = int(size)
        self._buf = np.zeros((self.size,) + shape)
        self.count = 0                     # innovations pushed so far (not capped)

    @property
    def full(self) -> bool:
        """True once `size` innovations have been pushed."""
        return self.count >= self.size

    def push(self, nu: np.ndarray) -> None:
        """Store one innovation, overwriting the oldest once the buffer is full."""
        self._buf[self.count % self.size] = nu
        self.count += 1

    def covariance(self) -> np.ndarray:
        """C_hat = (1/N) sum_j nu_j nu_j' over the stored innovations (only when full)."""
        if not self.full:
            raise ValueError("innovation window is not full yet")
        return np.einsum("k...i,k...j->...ij", self._buf, self._buf) / self.size


class InnovationVarianceWindow:
    """Per-row ring buffers of the last `size` innovations of each of m rows;
    `second_moment(rows)` is Sr_jj = mean nu_j^2 per row. With a batch shape (a stack of
    filters that see the same rows) each filter has its own buffers."""

    def __init__(self, m: int, size: int, batch: tuple[int, ...] = ()) -> None:
        if size < 1:
            raise ValueError(f"innovation window must be >= 1, got {size}")
        self.size = size
        self.buf = np.zeros(batch + (m, size))
        self.count = np.zeros(m, dtype=int)

    def push(self, rows: np.ndarray, nu: np.ndarray) -> None:
        """Store nu (one value per row in `rows`, (..., len(rows))) in those rows' buffers."""
        slot = self.count[rows] % self.size
        self.buf[..., rows, slot] = nu
        self.count[rows] += 1

    def full(self, rows: np.ndarray) -> np.ndarray:
        """Per row in `rows`: has it seen `size` innovations?"""
        return self.count[rows] >= self.size

    def second_moment(self, rows: np.ndarray) -> np.ndarray:
        """Sr_jj = (1/N) sum nu_j^2 over each row's buffer."""
        return np.mean(self.buf[..., rows, :] ** 2, axis=-1)
