"""Incremental PCA with a forgetting factor: the sequential Karhunen-Loeve update of IVT and ASLA.

Levy and Lindenbaum's update (IEEE TIP 2000) with Ross et al.'s mean update, as ``sklm.m`` of the
OTB benchmark's IVT and ASLA code computes it (github.com/jwlim/tracker_benchmark,
``trackers/IVT/sklm.m``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Subspace:
    """A mean, an orthonormal basis and its singular values, learnt from batches of patches.

    Attributes
    ----------
    mean : (N,) float64
    basis : (N, d) float64
        Orthonormal columns; ``d`` is 0 before the first update.
    singular_values : (d,) float64
        Descending.
    n_samples : float
        The effective number of patches seen (forgetting shrinks it).
    """

    mean: np.ndarray
    basis: np.ndarray = field(default=None)
    singular_values: np.ndarray = field(default=None)
    n_samples: float = 0.0

    def __post_init__(self) -> None:
        self.mean = np.asarray(self.mean, dtype=np.float64).ravel().copy()
        if self.basis is None:
            self.basis = np.zeros((self.mean.size, 0))
            self.singular_values = np.zeros(0)

    def update(self, data: np.ndarray, forgetting: float = 1.0, max_basis: int | None = None) -> None:
        """Add a batch of patches.

        Parameters
        ----------
        data : (N, n) float64
            One patch per column.
        forgetting : float
            ``ff`` of ``sklm.m``: the old singular values and sample count are scaled by it.
        max_basis : int, optional
            Keep at most this many basis vectors (``sklm.m``'s ``K``); without it, those whose
            squared singular value is at least 1e-6 of the total.
        """
        data = np.asarray(data, dtype=np.float64)
        n = data.shape[1]
        if self.basis.shape[1] == 0:
            # The first batch starts the subspace; the mean given at construction is replaced
            # (sklm.m's first branch), and the sample count is the batch's size.
            mean = data.mean(axis=1)
            if n == 1:
                basis = np.zeros((data.shape[0], 1))
                basis[0, 0] = 1.0
                self.mean, self.basis, self.singular_values = data[:, 0].copy(), basis, np.zeros(1)
                self.n_samples = 1.0
                return
            u, s, _ = np.linalg.svd(data - mean[:, None], full_matrices=False)
            keep = slice(None) if max_basis is None else slice(0, min(max_basis, s.size))
            self.mean, self.basis, self.singular_values = mean, u[:, keep], s[keep]
            self.n_samples = float(n)
            return
        n0 = self.n_samples
        batch_mean = data.mean(axis=1)
        centred = data - batch_mean[:, None]
        # The mean's own change enters as one more column (Ross et al. 2008, Sec. 3.1).
        centred = np.hstack([centred, np.sqrt(n * n0 / (n + n0)) * (self.mean - batch_mean)[:, None]])
        self.mean = (forgetting * n0 * self.mean + n * batch_mean) / (n + forgetting * n0)
        self.n_samples = n + forgetting * n0
        projection = self.basis.T @ centred
        residual = centred - self.basis @ projection
        q, _ = np.linalg.qr(residual)
        d = self.singular_values.size
        r = np.zeros((d + q.shape[1], d + centred.shape[1]))
        r[:d, :d] = forgetting * np.diag(self.singular_values)
        r[:d, d:] = projection
        r[d:, d:] = q.T @ residual
        u, s, _ = np.linalg.svd(r, full_matrices=False)
        if max_basis is None:
            keep = np.flatnonzero(s ** 2 >= (s ** 2).sum() * 1e-6)
        else:
            keep = np.arange(min(max_basis, s.size))
        self.basis = np.hstack([self.basis, q]) @ u[:, keep]
        self.singular_values = s[keep]

    def truncate(self, max_basis: int) -> None:
        """Keep the first ``max_basis`` basis vectors (IVT truncates after each update)."""
        self.basis = self.basis[:, :max_basis]
        self.singular_values = self.singular_values[:max_basis]

    def residuals(self, patches: np.ndarray) -> np.ndarray:
        """Each patch's squared distance to the subspace (mean plus span of the basis).

        Parameters
        ----------
        patches : (n, N) float64
            One patch per row.

        Returns
        -------
        (n,) float64
            ``||(x - mean) - U U^T (x - mean)||^2``.
        """
        difference = patches - self.mean
        if self.basis.shape[1]:
            difference -= (difference @ self.basis) @ self.basis.T
        return np.einsum("ij,ij->i", difference, difference)
