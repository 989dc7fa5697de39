"""Viscoelastic creep of the PapillArray's silicone pillars: the dynamics the lift and drift
simulators integrate over time (everything else in them is quasi-static, solved per sample).

Physics. A silicone pillar is a generalised Maxwell solid (Prony series): its relaxed spring
k_inf in parallel with Maxwell arms (k_i in series with a dashpot, relaxation time tau_i). The
parameters give g_i = k_i / k_0, the fraction of the instantaneous stiffness k_0 that relaxes with
tau_i (``creep_fractions``, ``creep_tau_s``); g_inf = 1 - sum(g_i) = k_inf / k_0. The pillar is
load-driven (the gripper is force-controlled, the weight is carried by friction): a force f(t)
deflects it by x(t), and the sensor reports k_inf x - its static calibration, exact once the
pillar has settled. With s_i = k_inf y_i (y_i the dashpot positions, in force units) the reading
r and the arm states obey, for every pillar and axis alike,

    r = g_inf f + sum_j g_j s_j,        ds_i/dt = (r - s_i) / tau_i,
i.e. ds/dt = A s + b f with A_ij = (g_j - delta_ij) / tau_i and b_i = g_inf / tau_i.

A step of force reads g_inf of its size at once and creeps to the full value (retardation times
of order tau_i / g_inf): the reading lags load changes, and a fast silicone mode (tau well below
the sample period) makes the system stiff. The force is known at the samples; between two
samples it is taken linear in time (first-order hold).

Integrators (``creep_integrator``, step h = sample period / ``creep_substeps``):
- ``exponential``: exact for a load linear between samples (matrix exponential of the augmented
  system); unconditionally stable; the default.
- ``implicit_euler``: backward Euler, unconditionally stable (L-stable), first order.
- ``rk4``: classical Runge-Kutta, fourth order, stable only for h |lambda| below about 2.785.
- ``euler``: forward Euler, first order, stable only for h |lambda| < 2.
The explicit methods are refused (ConfigError) when h is beyond their stability limit, unless the
caller asks otherwise (the integrator benchmark runs them there on purpose).

The Prony numbers of the real pillars are not published; the defaults in params.yaml are typical
of a soft platinum-cure silicone and are parameters to replace by a measured creep curve.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tactilepipe.core.errors import ConfigError

METHODS = ("exponential", "implicit_euler", "rk4", "euler")
RK4_LIMIT = 2.785293563405282      # real-axis stability limit of classical RK4


@dataclass(frozen=True)
class Prony:
    fractions: tuple[float, ...]   # g_i
    taus_s: tuple[float, ...]      # tau_i

    @classmethod
    def from_params(cls, sim: dict) -> "Prony":
        g = tuple(float(v) for v in sim["creep_fractions"])
        tau = tuple(float(v) for v in sim["creep_tau_s"])
        if len(g) != len(tau):
            raise ConfigError(f"simulate_volume: creep_fractions ({len(g)} values) and creep_tau_s "
                              f"({len(tau)} values) must have the same length")
        if any(v < 0 for v in g) or sum(g) >= 1.0:
            raise ConfigError(f"simulate_volume: creep_fractions {list(g)} must be >= 0 and sum to "
                              "less than 1 (the relaxed stiffness k_inf must stay positive)")
        if any(not np.isfinite(v) or v <= 0 for v in tau):
            raise ConfigError(f"simulate_volume: creep_tau_s {list(tau)} must be finite and > 0")
        return cls(g, tau)

    @property
    def g_inf(self) -> float:
        return 1.0 - sum(self.fractions)

    @property
    def active(self) -> bool:
        return any(g > 0 for g in self.fractions)

    def system(self) -> tuple[np.ndarray, np.ndarray]:
        """A (m, m) and b (m,) of ds/dt = A s + b f."""
        g = np.asarray(self.fractions, float)
        inv_tau = 1.0 / np.asarray(self.taus_s, float)
        a = inv_tau[:, None] * (g[None, :] - np.eye(len(g)))
        return a, self.g_inf * inv_tau

    def eigenvalues(self) -> np.ndarray:
        return np.linalg.eigvals(self.system()[0]) if self.fractions else np.zeros(0)


def stability_limit_s(prony: Prony, method: str) -> float:
    """Largest stable step (s) of ``method`` for this material (inf for the implicit ones).

    The eigenvalues of A are real and negative: A v = lam v is the symmetric-definite pencil
    (g g^T - diag(g)) v = lam diag(g tau) v, and g g^T - diag(g) is negative definite when
    sum(g) < 1 (Cauchy-Schwarz). So the real-axis limits of the explicit methods apply."""
    if method not in METHODS:
        raise ConfigError(f"simulate_volume.creep_integrator '{method}' must be one of {list(METHODS)}")
    lam = np.abs(np.real(prony.eigenvalues()))
    if method in ("exponential", "implicit_euler") or len(lam) == 0:
        return float("inf")
    return float((2.0 if method == "euler" else RK4_LIMIT) / lam.max())


def step_matrices(prony: Prony, h: float, method: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Phi, G0, G1) with s_next = Phi s + G0 f_start + G1 f_end for one step of length h, the load
    linear over the step. Every method here is linear in (s, f), so one step is this affine map;
    ``integrate`` applies it step by step."""
    a, b = prony.system()
    m = len(b)
    eye = np.eye(m)
    if method == "exponential":
        from scipy.linalg import expm     # here, not at the top: the workflow imports this module
                                          # when it plans jobs, and scipy costs each Snakemake start
        aug = np.zeros((m + 2, m + 2))
        aug[:m, :m], aug[:m, m], aug[m, m + 1] = a, b, 1.0 / h
        e = expm(aug * h)                   # u' = (f_end - f_start) / h over the step
        phi, g_u, g_v = e[:m, :m], e[:m, m], e[:m, m + 1]
        return phi, g_u - g_v, g_v
    if method == "implicit_euler":
        inv = np.linalg.inv(eye - h * a)
        return inv, np.zeros(m), h * inv @ b
    if method == "euler":
        return eye + h * a, h * b, np.zeros(m)
    if method == "rk4":
        # stages with the load at t, t + h/2 (mean of the ends) and t + h
        ha = h * a
        phi = eye + ha + ha @ ha / 2 + ha @ ha @ ha / 6 + ha @ ha @ ha @ ha / 24
        k1_0 = b                                                     # f-terms of each stage: (start, end)
        k2 = (b / 2 + ha @ k1_0 / 2, b / 2)
        k3 = (b / 2 + ha @ k2[0] / 2, b / 2 + ha @ k2[1] / 2)
        k4 = (ha @ k3[0], b + ha @ k3[1])
        g0 = h / 6 * (k1_0 + 2 * k2[0] + 2 * k3[0] + k4[0])
        g1 = h / 6 * (2 * k2[1] + 2 * k3[1] + k4[1])
        return phi, g0, g1
    raise ConfigError(f"simulate_volume.creep_integrator '{method}' must be one of {list(METHODS)}")


def sample_map(prony: Prony, dt: float, method: str, substeps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Phi, P, Q): one sample period of ``substeps`` steps, s_next = Phi s + P f_n + Q f_{n+1}
    (the load linear between the samples, evaluated at every substep)."""
    phi, g0, g1 = step_matrices(prony, dt / substeps, method)
    m = len(g0)
    big, p, q = np.eye(m), np.zeros(m), np.zeros(m)
    for k in range(substeps):
        a0, a1 = k / substeps, (k + 1) / substeps
        big = phi @ big
        p = phi @ p + g0 * (1 - a0) + g1 * (1 - a1)
        q = phi @ q + g0 * a0 + g1 * a1
    return big, p, q


def integrate(force: np.ndarray, dt: float, prony: Prony, method: str = "exponential",
              substeps: int = 1, check_stability: bool = True) -> np.ndarray:
    """Sensor reading of load-driven viscoelastic pillars.

    force: (T, ...) true pillar forces at samples dt apart (starting from rest: relaxed, unloaded).
    Returns the readings, same shape, float64.

    The chosen method's step is an affine map of (s, f), so a whole sample period is one map and the
    recursion runs per mode with ``scipy.signal.lfilter``: the same numbers as stepping, much faster
    (``benchmarks/bench_integrators.py`` times both and prints their difference).
    """
    force = np.asarray(force, np.float64)
    if not prony.active or len(force) == 0:
        return force.copy()
    if method not in METHODS:
        raise ConfigError(f"simulate_volume.creep_integrator '{method}' must be one of {list(METHODS)}")
    if int(substeps) < 1:
        raise ConfigError(f"simulate_volume.creep_substeps must be >= 1 (got {substeps})")
    substeps = int(substeps)
    h = dt / substeps
    limit = stability_limit_s(prony, method)
    if check_stability and h > limit:
        raise ConfigError(
            f"simulate_volume.creep_integrator '{method}' is unstable at a step of {h * 1e3:.3g} ms "
            f"(sample period {dt * 1e3:.3g} ms / {substeps} substeps): its limit for the fastest "
            f"creep mode is {limit * 1e3:.3g} ms. Use 'exponential' or 'implicit_euler', or "
            f"creep_substeps >= {int(np.ceil(dt / limit))}")
    shape = force.shape
    f = force.reshape(len(force), -1)
    g = np.asarray(prony.fractions, float)
    with np.errstate(over="ignore", invalid="ignore"):
        out = _modal(f, dt, substeps, prony, method, g)
    return out.reshape(shape)


def _modal(f, dt, substeps, prony, method, g):
    """z_n = s_n - Q f_n follows z_{n+1} = Phi z_n + (Phi Q + P) f_n; in the eigenbasis of A (shared
    by Phi, real: see stability_limit_s) every mode is a first-order recursion."""
    from scipy.signal import lfilter      # here, not at the top: see step_matrices

    big, p, q = sample_map(prony, dt, method, substeps)
    lam, vec = np.linalg.eig(prony.system()[0])
    vec = np.real(vec)
    inv = np.linalg.inv(vec)
    mu = np.real(np.diag(inv @ big @ vec))
    beta = inv @ (big @ q + p)
    readout = g @ vec
    z0 = -np.outer(f[0], inv @ q)                       # s_0 = 0
    out = (prony.g_inf + g @ q) * f
    for k in range(len(mu)):
        mode = lfilter([0.0, beta[k]], [1.0, -mu[k]], f, axis=0, zi=z0[None, :, k])[0]
        out += readout[k] * mode
    return out


def integrate_params(force: np.ndarray, dt: float, sim: dict) -> np.ndarray:
    """``integrate`` with the simulate_volume parameters (no creep when creep_fractions is empty)."""
    return integrate(force, dt, Prony.from_params(sim), sim["creep_integrator"],
                     sim["creep_substeps"])
