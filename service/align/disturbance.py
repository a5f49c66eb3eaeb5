"""Motion that breaks the fixed-base model (alignment-math.md §3; issue "robustness").

Inertial-frame alignment of a base fixed in position explains α(t) = C_{b0}^{n0} β(t) with a
constant C_{b0}^{n0}: rotation of any kind (swing, turning on the spot) is carried by C_b^{b0}
and never shows. A base that translates adds its velocity change to α and nothing to β. With an
estimate of C_{b0}^{n0} taken a little earlier (so that the fit has not yet bent itself around
the new motion), the horizontal part of C_{b0}^{n0} α − β is the velocity the base has gained:
a few mm/s for a swinging or moored base, metres per second within seconds for a driven one.
"""
from __future__ import annotations

import numpy as np

from .observations import ObservationSource


def translation_residual_mps(source: ObservationSource, C_b0_n0: np.ndarray, elapsed_s: float,
                             q_b_b0: np.ndarray, alpha_b0: np.ndarray) -> float:
    """|horizontal part of C_{b0}^{n0} α − β| (m/s) at ``elapsed_s`` after the start."""
    _, beta = source.vectors(np.array([elapsed_s]), alpha_b0[None], q_b_b0[None])
    residual = C_b0_n0 @ alpha_b0 - beta[0]
    return float(np.hypot(residual[0], residual[1]))
