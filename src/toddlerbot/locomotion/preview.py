"""Cart-table model and ZMP preview control (Kajita et al., ICRA 2003; servo form of Katayama et al. 1985).

The CoM moves at constant height z_c; with the CoM jerk as input, each horizontal axis is the discrete system

    x_{k+1} = A x_k + B u_k,  x = (c, c_dot, c_ddot),  p_k = C x_k = c - z_c / g * c_ddot   (the ZMP)

and the controller minimises sum Q_e e_k^2 + R u_k^2 with e the ZMP error, looking ``N`` ticks ahead:

    u_k = -G_i sum_{i<=k} e_i - G_x x_k - sum_{j=1..N} G_d[j] p_ref_{k+j}
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_discrete_are

GRAVITY = 9.81


@dataclass(frozen=True)
class PreviewGains:
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    Gi: float
    Gx: np.ndarray
    """(3,) state feedback gains."""
    Gd: np.ndarray
    """(N,) preview gains on p_ref_{k+1..k+N}."""


def preview_gains(dt: float, com_height: float, n_preview: int, q_zmp: float, r_jerk: float) -> PreviewGains:
    """Gains of the ZMP preview servo for a cart-table of height ``com_height`` (m) sampled every ``dt`` s."""
    A = np.array([[1.0, dt, dt * dt / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    B = np.array([[dt**3 / 6], [dt * dt / 2], [dt]])
    C = np.array([[1.0, 0.0, -com_height / GRAVITY]])
    # augmented system: (integrated ZMP error, state increment)
    At = np.block([[np.eye(1), C @ A], [np.zeros((3, 1)), A]])
    Bt = np.vstack([C @ B, B])
    Qt = np.zeros((4, 4))
    Qt[0, 0] = q_zmp
    R = np.array([[r_jerk]])
    P = solve_discrete_are(At, Bt, Qt, R)
    S = R + Bt.T @ P @ Bt
    K = np.linalg.solve(S, Bt.T @ P @ At)
    Ac = At - Bt @ K
    X = -Ac.T @ P @ np.array([[1.0], [0.0], [0.0], [0.0]])
    Gd = np.empty(n_preview)
    Gd[0] = -K[0, 0]
    for j in range(1, n_preview):
        Gd[j] = np.linalg.solve(S, Bt.T @ X)[0, 0]
        X = Ac.T @ X
    return PreviewGains(A=A, B=B[:, 0], C=C[0], Gi=float(K[0, 0]), Gx=K[0, 1:].copy(), Gd=Gd)


def preview_step(
    gains: PreviewGains, x: np.ndarray, err_sum: np.ndarray, zmp_future: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Advance both horizontal axes one tick.

    x: (3, 2) cart state (position, velocity, acceleration) for x and y; err_sum: (2,) integrated ZMP error;
    zmp_future: (N + 1, 2) ZMP reference for ticks k .. k+N. Returns (x_next, err_sum_next, zmp_k).
    """
    zmp = gains.C @ x
    err_sum = err_sum + zmp - zmp_future[0]
    u = -gains.Gi * err_sum - gains.Gx @ x - gains.Gd @ zmp_future[1:]
    x_next = gains.A @ x + np.outer(gains.B, u)
    return x_next, err_sum, zmp
