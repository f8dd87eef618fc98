"""Central differences: the independent check of the analytic derivatives the physics tests assert."""

from __future__ import annotations

import numpy as np


def central(f, x: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """``f``'s derivative at ``x`` by central differences, one row per element of ``x`` (a scalar
    ``f``: its gradient; a vector one: its Jacobian transposed)."""
    return np.array([(f(x + e) - f(x - e)) / (2 * eps) for e in np.eye(len(x)) * eps])


def rel(a: np.ndarray, b: np.ndarray) -> float:
    """``a``'s error against ``b``, relative to ``b`` (Frobenius norms)."""
    return float(np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300))
