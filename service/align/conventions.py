"""Frames, attitude representations and unit conversions: the one place that pins them.

Frames (docs/algorithms/conventions.md):
    n   local-level navigation frame, East-North-Up (ENU)
    b   IMU body frame, Right-Front-Up (x right, y forward, z up)
    n0, b0  inertially frozen copies of n and b at the alignment start

Names put the destination frame first: ``C_b_n`` is C_b^n, mapping body vectors to navigation
vectors (``v_n = C_b_n @ v_b``); ``q_b_n = [w, x, y, z]`` (scalar first, Hamilton product) is
the same rotation, ``v_n = q ⊗ v_b ⊗ q*``.

Euler angles are for display only: pitch θ about body x (nose up +), roll γ about body y
(right wing down +), heading ψ clockwise from true North in [0°, 360°);
``C_b_n = Rz(-ψ) · Rx(θ) · Ry(γ)``.

Misalignment φ (n-frame components φ_E, φ_N, φ_U) of an estimate:
``C_b_n_est = (I - [φ×]) C_b_n_true``; the heading error (estimate - truth, clockwise) is ≈ +φ_U.

Every function is vectorised over leading axes: a quaternion is ``(..., 4)``, a DCM
``(..., 3, 3)``, a vector ``(..., 3)``.
"""
from __future__ import annotations

import math

import numpy as np

from ._attitude import dcm_from_quat_one, with_heading_of_one

DEG = np.pi / 180.0
"""One degree in rad."""
DH_TO_RS = DEG / 3600.0
"""°/h → rad/s."""
DRH_TO_RRS = DEG / 60.0
"""°/√h → rad/√s (angle random walk)."""
UG_TO_MS2 = 9.80665e-6
"""µg → m/s² (standard gravity, the datasheet unit)."""
EYE3 = np.eye(3)
"""The 3×3 identity, read-only: made once, not in every call of a per-step function."""
EYE3.flags.writeable = False


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix [v×], so that ``skew(a) @ b == cross(a, b)``. Shape (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    S = np.zeros((*v.shape[:-1], 3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of (..., 3) vectors (broadcasting); np.cross without its per-call overhead."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    a1, a2, a3 = a[..., 0], a[..., 1], a[..., 2]
    b1, b2, b3 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack((a2 * b3 - a3 * b2, a3 * b1 - a1 * b3, a1 * b2 - a2 * b1), axis=-1)


def quat_multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p ⊗ q of [w, x, y, z] quaternions (broadcasting)."""
    p, q = np.asarray(p, dtype=float), np.asarray(q, dtype=float)
    pw, px, py, pz = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qw, qx, qy, qz = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack((pw * qw - px * qx - py * qy - pz * qz,
                     pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw), axis=-1)


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternion with a non-negative scalar part (one of the two signs, chosen fixed).

    The norm is written out element by element, so a quaternion gets the same bits whatever the
    shape of the array it sits in (the pipeline's live and offline paths rely on it).
    """
    q = np.asarray(q, dtype=float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    q = q / np.sqrt(w * w + x * x + y * y + z * z)[..., None]
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_from_rotvec(phi: np.ndarray) -> np.ndarray:
    """Quaternion of the rotation vector φ (rad): exp(φ/2), closed form, exact for any angle."""
    phi = np.asarray(phi, dtype=float)
    angle = np.linalg.norm(phi, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(x)/x by its series below 1e-4 rad, where the series is exact to double precision
    small = half < 1e-4
    safe = np.where(small, 1.0, half)
    k = np.where(small, 0.5 * (1.0 - half * half / 6.0), 0.5 * np.sin(safe) / safe)
    return np.concatenate((np.cos(half), k * phi), axis=-1)


def rotvec_from_quat(q: np.ndarray) -> np.ndarray:
    """Rotation vector (rad, angle in [0, π]) of a unit quaternion."""
    q = quat_normalize(q)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., :1])
    scale = np.where(s > 1e-12, angle / np.where(s > 1e-12, s, 1.0), 2.0)
    return scale * v


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """C(q) v for unit quaternions q, without forming the matrix."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * cross(u, v)
    return v + w * t + cross(u, t)


def dcm_from_quat(q: np.ndarray) -> np.ndarray:
    """Direction cosine matrix of a unit quaternion: C = (w² - u·u) I + 2 u uᵀ + 2 w [u×]. One quaternion goes
    through the compiled formula (service/align/_attitude.pyx, the same bits): the records and checks' case."""
    q = np.asarray(q, dtype=float)
    if q.shape == (4,):
        return dcm_from_quat_one(np.ascontiguousarray(q))
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    xx, yy, zz, xy, xz, yz, wx, wy, wz = x * x, y * y, z * z, x * y, x * z, y * z, w * x, w * y, w * z
    C = np.empty((*q.shape[:-1], 3, 3))   # filled in place: numpy's per-call cost dominates a few quaternions
    C[..., 0, 0], C[..., 0, 1], C[..., 0, 2] = 1 - 2 * (yy + zz), 2 * (xy - wz), 2 * (xz + wy)
    C[..., 1, 0], C[..., 1, 1], C[..., 1, 2] = 2 * (xy + wz), 1 - 2 * (xx + zz), 2 * (yz - wx)
    C[..., 2, 0], C[..., 2, 1], C[..., 2, 2] = 2 * (xz - wy), 2 * (yz + wx), 1 - 2 * (xx + yy)
    return C


def quat_from_dcm(C: np.ndarray) -> np.ndarray:
    """Unit quaternion (w ≥ 0) of a rotation matrix C (..., 3, 3), by Shepperd's method.

    For a rotation, 4 q qᵀ = K + I with Bar-Itzhack's symmetric K; its diagonal holds 4 q_i², and the column of the
    largest one is q times a factor far from zero, normalised: exact for every rotation, 180° turns included, with
    no eigen-solve. A slightly non-orthogonal C gives a quaternion off its nearest rotation by the order of C's
    error. One matrix goes through plain floats (the records' case, no numpy call per element); a stack through
    the same operations in numpy: the same bits either way.
    """
    C = np.asarray(C, dtype=float)
    if C.shape == (3, 3):
        return np.array(_shepperd(*C.ravel().tolist()))
    c00, c01, c02 = C[..., 0, 0], C[..., 0, 1], C[..., 0, 2]
    c10, c11, c12 = C[..., 1, 0], C[..., 1, 1], C[..., 1, 2]
    c20, c21, c22 = C[..., 2, 0], C[..., 2, 1], C[..., 2, 2]
    d = np.stack((1.0 + c00 + c11 + c22, 1.0 + c00 - c11 - c22, 1.0 - c00 + c11 - c22, 1.0 - c00 - c11 + c22), -1)
    wx, wy, wz = c21 - c12, c02 - c20, c10 - c01
    xy, xz, yz = c10 + c01, c02 + c20, c21 + c12
    columns = np.stack((np.stack((d[..., 0], wx, wy, wz), -1), np.stack((wx, d[..., 1], xy, xz), -1),
                        np.stack((wy, xy, d[..., 2], yz), -1), np.stack((wz, xz, yz, d[..., 3]), -1)), -2)
    best = np.argmax(d, axis=-1)[..., None, None]
    return quat_normalize(np.take_along_axis(columns, best, axis=-2)[..., 0, :])


def _shepperd(c00: float, c01: float, c02: float, c10: float, c11: float, c12: float, c20: float, c21: float,
              c22: float) -> tuple[float, float, float, float]:
    """:func:`quat_from_dcm` of one matrix in plain floats, operation for operation (then quat_normalize's)."""
    d = (1.0 + c00 + c11 + c22, 1.0 + c00 - c11 - c22, 1.0 - c00 + c11 - c22, 1.0 - c00 - c11 + c22)
    wx, wy, wz = c21 - c12, c02 - c20, c10 - c01
    xy, xz, yz = c10 + c01, c02 + c20, c21 + c12
    best = d.index(max(d))
    w, x, y, z = ((d[0], wx, wy, wz), (wx, d[1], xy, xz), (wy, xy, d[2], yz), (wz, xz, yz, d[3]))[best]
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    return (-w, -x, -y, -z) if w < 0.0 else (w, x, y, z)


def dcm_from_euler(heading: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """C_b^n = Rz(-heading) Rx(pitch) Ry(roll); angles in rad, heading clockwise from North."""
    heading, pitch, roll = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (heading, pitch, roll)))
    sh, ch = np.sin(heading), np.cos(heading)
    sp, cp = np.sin(pitch), np.cos(pitch)
    sr, cr = np.sin(roll), np.cos(roll)
    return np.stack((
        np.stack((ch * cr + sh * sp * sr, sh * cp, ch * sr - sh * sp * cr), -1),
        np.stack((-sh * cr + ch * sp * sr, ch * cp, -sh * sr - ch * sp * cr), -1),
        np.stack((-cp * sr, sp, cp * cr), -1),
    ), axis=-2)


def euler_from_dcm(C_b_n: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(heading in [0, 2π), pitch, roll) in rad of C_b^n."""
    C = np.asarray(C_b_n, dtype=float)
    heading = np.mod(np.arctan2(C[..., 0, 1], C[..., 1, 1]), 2.0 * np.pi)
    pitch = np.arcsin(np.clip(C[..., 2, 1], -1.0, 1.0))
    roll = np.arctan2(-C[..., 2, 0], C[..., 2, 2])
    return heading, pitch, roll


def misalignment(C_b_n_est: np.ndarray, C_b_n_true: np.ndarray) -> np.ndarray:
    """φ (rad, n-frame E/N/U) with C_est = exp(-[φ×]) C_true ≈ (I - [φ×]) C_true; φ_U ≈ heading error."""
    M = np.asarray(C_b_n_est) @ np.swapaxes(np.asarray(C_b_n_true), -1, -2)
    return -rotvec_from_quat(quat_from_dcm(M))


def with_heading_of(C_b_n_level: np.ndarray, C_b_n_heading: np.ndarray) -> np.ndarray:
    """C_b^n (3, 3) with the level (tilt) of ``C_b_n_level`` and the heading of ``C_b_n_heading``: the first turned
    about the n-frame Up axis by their heading difference φ_U, the Up component of :func:`misalignment` (a turn about
    Up leaves the tilt as it is). Compiled (service/align/_attitude.pyx): it runs at every record."""
    return with_heading_of_one(np.asarray(C_b_n_level, dtype=float), np.asarray(C_b_n_heading, dtype=float))


def wrap_pi(angle: np.ndarray) -> np.ndarray:
    """Wrap an angle (rad) into [-π, π)."""
    return np.mod(np.asarray(angle) + np.pi, 2.0 * np.pi) - np.pi
