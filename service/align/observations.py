"""Observation sources of inertial-frame alignment: vector pairs b_k = C_n^b(0) r_k (docs/algorithms/coarse.md).

A source turns the integrator's output at the observation epochs (α(t) and C_{b(t)}^{b0}) into
an observation vector b in b0 axes and a reference vector r in n0 axes, and knows how the
navigation frame turns, C_{n(t)}^{n0}. The coarse alignment and its solvers do not care where
the pairs come from: aided modes (odometer/DVL velocity, GNSS velocity or position, a master
INS) are further sources with the same two methods.
"""
from __future__ import annotations

from typing import Protocol

import numpy as np

from ._kernels import C_n_n0_fixed_at, beta_fixed_many
from .earth import Site


class ObservationSource(Protocol):
    site: Site
    """Position at the alignment start (sets latitude and gravity of the σ model)."""

    def vectors(self, elapsed_s: np.ndarray, alpha_b0: np.ndarray, q_b_b0: np.ndarray,
                aid: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(b, r), each (M, 3), not necessarily unit, at M epochs ``elapsed_s`` after the start.

        ``aid`` (M, k): the aiding values at those epochs (all finite), for aided sources."""
        ...

    def C_n_n0(self, elapsed_s: float) -> np.ndarray:
        """C_{n(t)}^{n0} (3, 3) at ``elapsed_s`` after the start."""
        ...


class FixedSiteSource:
    """A base that does not translate (static, swinging, turntable): b = α, r = β (closed form)."""

    def __init__(self, site: Site) -> None:
        self.site = site
        self._gravity = site.gravity

    def vectors(self, elapsed_s: np.ndarray, alpha_b0: np.ndarray, q_b_b0: np.ndarray,
                aid: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        return alpha_b0, beta_fixed_many(self.site.lat, self._gravity, elapsed_s)   # compiled: beta_fixed's bits

    def C_n_n0(self, elapsed_s: float) -> np.ndarray:
        return C_n_n0_fixed_at(self.site.lat, float(elapsed_s))   # compiled: the same bits as C_n_n0_fixed
