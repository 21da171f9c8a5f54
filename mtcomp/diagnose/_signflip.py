"""A laser file the diagnosis leaves unexplained, tried with its sign reversed
(:mod:`mtcomp.identification.signflip`, on diagnose's linearised design: the final model's columns,
the target of each laser file's reversal as one more right-hand side of one least-squares solve)."""
from __future__ import annotations

import numpy as np

from ..identification.signflip import sign_note


def reversed_sign_note(st, design, extra: np.ndarray) -> str | None:
    """One line naming the laser file whose readings agree with the rest with their sign reversed
    under the final model (its common block ``design`` and ``extra`` columns), None otherwise."""
    n_files = len(st.paths)
    lasers = [i for i in range(n_files) if st.kinds[i] == "laser" and np.any(st.file == i)]
    if n_files < 2 or not lasers:
        return None
    Z = np.repeat(design.z[:, None], 1 + len(lasers), axis=1)
    for j, i in enumerate(lasers, start=1):
        rows = st.file == i
        Z[rows, j] -= 2.0 * st.y[rows]
    A = np.hstack([design.A, extra]) * design.w[:, None]
    coef = np.linalg.lstsq(A, Z * design.w[:, None], rcond=None)[0]
    R = Z - np.hstack([design.A, extra]) @ coef            # error units (um, urad)
    rms = np.array([np.sqrt(np.mean(R[st.file == i] ** 2, axis=0)) if np.any(st.file == i)
                    else np.zeros(R.shape[1]) for i in range(n_files)])
    sse = np.sum((R * design.w[:, None]) ** 2, axis=0)
    units = [str(st.unit[st.file == i][0]) if np.any(st.file == i) else "" for i in range(n_files)]
    return sign_note(rms, sse, lasers, list(zip(st.paths, units)))
