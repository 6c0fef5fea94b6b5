"""Numbers published in the paper (Montone, Donnarumma & Prevete, ICANNGA 2011), as printed.

Indices in the code are 0-based: the paper's ``W_23`` (1-based, neuron 3 -> neuron 2) is
``W[1, 2]`` here. These matrices are what section 3.1 prints; ``docs/paper-values.md`` records
what they do and do not do.
"""

from __future__ import annotations

import numpy as np

from mbn.networks.ctrnn import CTRNN, make_ctrnn

__all__ = ["DEFAULT_TAU", "WE_LF", "WE_RF", "W_LF", "W_RF", "published_lf", "published_rf"]

#: Right-follower recurrent weights, section 3.1.
W_RF = np.array([[178.2, -457.4, -335.1], [-365.3, -73.4, 66.3], [883.0, 422.2, -266.1]])
#: Right-follower input weights, section 3.1 (neuron k receives input k).
WE_RF = np.array([[0.0, 0.0, 0.0], [0.0, -19.0, 0.0], [0.0, 0.0, 769.5]])
#: Left-follower recurrent weights: W_RF with W_23 changed from 66.3 to -4.
W_LF = np.array([[178.2, -457.4, -335.1], [-365.3, -73.4, -4.0], [883.0, 422.2, -266.1]])
#: Left-follower input weights: WE_22 changed from -19 to 0 and WE_21 from 0 to 18.
WE_LF = np.array([[0.0, 0.0, 0.0], [18.0, 0.0, 0.0], [0.0, 0.0, 769.5]])

#: The paper gives no value for the shared time constant tau; 0.5 s is this project's default
#: (an earlier study here evolved working wall followers with it). The multipliers run at tau/10.
DEFAULT_TAU = 0.5


def published_rf(tau: float = DEFAULT_TAU, dtype: object = None) -> CTRNN:
    """The published right-follower as a :class:`~mbn.networks.ctrnn.CTRNN` (no biases, unit
    gains)."""
    return make_ctrnn(W_RF, WE_RF, tau, dtype=dtype, name="published RF")


def published_lf(tau: float = DEFAULT_TAU, dtype: object = None) -> CTRNN:
    """The published left-follower as a :class:`~mbn.networks.ctrnn.CTRNN` (no biases, unit
    gains)."""
    return make_ctrnn(W_LF, WE_LF, tau, dtype=dtype, name="published LF")
