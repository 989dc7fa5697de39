"""The study-001 MLP: one ReLU hidden layer, linear output, Adam, L2, minibatches, tol stopping.

This is scikit-learn's MLPRegressor algorithm (Glorot-uniform init, squared loss / 2 plus
alpha/2n·||W||², Adam with beta 0.9/0.999, eps 1e-8, reshuffled minibatches, stop after
``n_iter_no_change`` epochs without a ``tol`` gain in training loss) written in NumPy:
sklearn's per-batch overhead made one fit on a 140k-sample fold take ~18 s, this one takes a
few seconds, and `tests/unit/test_volume_models.py` (test_mlp_matches_sklearn) checks both reach
the same accuracy. Inputs and target are
standardised with training statistics only.

A 2-unit ReLU layer sometimes starts with both units dead and settles on a constant (R² ≈ 0);
``restarts`` independent initialisations are trained and the one with the lowest *training*
loss is kept, so the choice never looks at test data.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tactilepipe.core.errors import ArgumentError, TactilepipeError

_ROUND_OFF = 16 * np.finfo(np.float64).eps     # relative spread below which a column is constant


class MLPDivergedError(TactilepipeError, FloatingPointError):
    """The training loss became NaN or inf; the message names the epoch, batch and restart."""


@dataclass
class MLPConfig:
    hidden_units: int = 2
    alpha: float = 1e-4
    batch_size: int = 200
    learning_rate: float = 1e-3
    tol: float = 1e-4
    n_iter_no_change: int = 10
    max_iter: int = 200
    restarts: int = 3

    @classmethod
    def from_params(cls, p: dict, **overrides) -> "MLPConfig":
        # every field from the parameters: a key missing there is an error, not a silent default
        return cls(**{**{k: p[k] for k in cls.__dataclass_fields__}, **overrides})


@dataclass
class MLPRegressor:
    config: MLPConfig
    seed: int = 0
    weights: list = field(default_factory=list)
    loss_curve: list = field(default_factory=list)
    n_iter: int = 0
    converged: bool = False
    constant_target: bool = False     # fitted on one label value: predicts it, R² is undefined

    def fit(self, x: np.ndarray, y: np.ndarray) -> "MLPRegressor":
        x = np.asarray(x, np.float64)
        y = np.asarray(y, np.float64).reshape(-1)
        if x.ndim != 2 or len(x) != len(y) or len(y) == 0:
            raise ArgumentError(f"fit needs x (n, d) and y (n,), got {x.shape} and {y.shape}")
        if not (np.isfinite(x).all() and np.isfinite(y).all()):
            rows = np.flatnonzero(~(np.isfinite(x).all(axis=1) & np.isfinite(y)))
            raise ArgumentError(f"fit: inputs (x) or targets (y) contain NaN or inf ({len(rows)} samples, "
                                f"first rows {rows[:5].tolist()})")
        cfg = self.config
        # each restart has its own initialisation stream (restart 0 is the restarts=1 network);
        # the minibatch order has another
        inits = [np.random.default_rng(np.random.SeedSequence([self.seed, k])) for k in range(max(1, cfg.restarts))]
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, 2**31]))
        # standardise with training statistics; a column constant up to its float round-off (its
        # "spread" is rounding noise) is only centred, so a constant target gives a constant model
        self.x_mean, self.x_std = x.mean(0), x.std(0)
        self.x_std[self.x_std <= _ROUND_OFF * np.abs(x).max(0)] = 1.0
        self.y_mean, self.y_std = y.mean(), y.std()
        if self.y_std <= _ROUND_OFF * np.abs(y).max():
            # one class / a constant label: the least-squares model is that constant; training a
            # network on rounding noise would only add its random initial outputs to it
            d, h = x.shape[1], cfg.hidden_units
            self.y_std = 1.0
            self.weights = [np.zeros((d, h)), np.zeros((1, h)), np.zeros((h, 1)), np.zeros((1, 1))]
            self.loss_curve, self.n_iter, self.converged, self.constant_target = [], 0, True, True
            return self
        self.constant_target = False
        xs = (x - self.x_mean) / self.x_std
        ys = ((y - self.y_mean) / self.y_std)[:, None]
        n, d = xs.shape
        h, r = cfg.hidden_units, max(1, cfg.restarts)
        # The restarts train side by side as one batched network (leading axis r): same
        # minibatches, independent initialisations, each stops on its own tol criterion.
        b1, b2 = np.sqrt(6.0 / (d + h)), np.sqrt(6.0 / (h + 1))
        params = [np.stack([g.uniform(-b, b, shape) for g in inits])
                  for b, shape in ((b1, (d, h)), (b1, (1, h)), (b2, (h, 1)), (b2, (1, 1)))]
        m = [np.zeros_like(p) for p in params]
        v = [np.zeros_like(p) for p in params]
        beta1, beta2, eps = 0.9, 0.999, 1e-8
        batch = min(cfg.batch_size, n)
        active = np.ones(r, bool)
        steps = np.zeros(r)
        best = np.full(r, np.inf)
        stall = np.zeros(r, int)
        curves: list[list[float]] = [[] for _ in range(r)]
        for epoch in range(cfg.max_iter):
            order = rng.permutation(n)
            xp, yp = xs[order], ys[order]
            total = np.zeros(r)
            gate = active[:, None, None].astype(np.float64)
            for b, start in enumerate(range(0, n, batch), start=1):
                xb, yb = xp[start:start + batch], yp[start:start + batch]
                nb = len(xb)
                w1, c1, w2, c2 = params
                with np.errstate(over="ignore", invalid="ignore"):   # checked just below
                    z = xb @ w1 + c1                       # (r, nb, h)
                    a = np.maximum(z, 0.0)
                    err = a @ w2 + c2 - yb                 # (r, nb, 1)
                    batch_loss = 0.5 * (err ** 2).sum(axis=(1, 2)) + 0.5 * cfg.alpha * (
                        (w1 ** 2).sum(axis=(1, 2)) + (w2 ** 2).sum(axis=(1, 2)))
                bad = active & ~np.isfinite(batch_loss)
                if bad.any():
                    k = int(np.argmax(bad))
                    raise MLPDivergedError(
                        f"MLP training stopped: non-finite loss ({batch_loss[k]}) at epoch {epoch + 1}, "
                        f"batch {b} of {-(-n // batch)} (restart {k + 1} of {r}); inputs and targets are "
                        f"finite, so the weights diverged (learning_rate {cfg.learning_rate:g} too large?)")
                total += batch_loss
                g_out = err / nb
                g_w2 = a.transpose(0, 2, 1) @ g_out + cfg.alpha * w2 / nb
                g_c2 = g_out.sum(axis=1, keepdims=True)
                g_a = (g_out @ w2.transpose(0, 2, 1)) * (z > 0)
                g_w1 = xb.T @ g_a + cfg.alpha * w1 / nb
                g_c1 = g_a.sum(axis=1, keepdims=True)
                steps += active                        # Adam step count; frozen restarts stay put
                t = np.maximum(steps, 1.0)
                lr = (cfg.learning_rate * np.sqrt(1 - beta2 ** t) / (1 - beta1 ** t))[:, None, None]
                for p, g, mi, vi in zip(params, (g_w1, g_c1, g_w2, g_c2), m, v):
                    mi *= beta1
                    mi += (1 - beta1) * g
                    vi *= beta2
                    vi += (1 - beta2) * g * g
                    p -= gate * lr * mi / (np.sqrt(vi) + eps)
            loss = total / n
            for k in np.flatnonzero(active):
                curves[k].append(float(loss[k]))
                stall[k] = stall[k] + 1 if loss[k] > best[k] - cfg.tol else 0
                best[k] = min(best[k], loss[k])
                if stall[k] > cfg.n_iter_no_change:
                    active[k] = False
            if not active.any():
                break
        k = int(np.argmin([c[-1] for c in curves]))   # lowest final training loss wins
        self.weights = [p[k] for p in params]
        self.loss_curve = curves[k]
        self.n_iter = len(curves[k])
        self.converged = not active[k]
        return self

    def predict(self, x: np.ndarray) -> np.ndarray:
        w1, c1, w2, c2 = self.weights
        xs = (np.asarray(x, np.float64) - self.x_mean) / self.x_std
        return (np.maximum(xs @ w1 + c1, 0.0) @ w2 + c2)[:, 0] * self.y_std + self.y_mean
