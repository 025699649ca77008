"""The controller of the independent references (tests/*_reference.py), written apart from dfwb's LinearSystem.

G(s) = (b0 s^n + ... + bn) / (s^n + a1 s^(n-1) + ... + an) in controllable canonical form: z' = Ac z + e_n y,
G(s) y = Cz . z + b0 y (y the plant's output).
"""

import numpy as np


def canonical(b, a):
    """(Ac, Cz, b0) of G = b/a: numpy arrays Ac (n x n) and Cz (n), the feedthrough b0 a float."""
    n = len(a)
    a_, b_ = np.asarray(a, float), np.zeros(n + 1)
    b_[n + 1 - len(b):] = b  # b0..bn, leading zeros for a proper G
    Ac = np.zeros((n, n))
    Ac[:-1, 1:] = np.eye(n - 1)
    Ac[-1, :] = -a_[::-1]
    Cz = b_[:0:-1] - a_[::-1] * b_[0]  # (bn - an b0, ..., b1 - a1 b0)
    return Ac, Cz, float(b_[0])
