"""Arc-length profiles of the gradient effects: exp(γ·(s/S − ½)) at the position s of a joint
(or link centre) along the arc S, normalised at mid-length so that γ changes the distribution
and not the mean level (which stays with E, ζ or the density of the base model)."""

from __future__ import annotations

import numpy as np

from pipeline.model.whisker import WhiskerChain


def joint_arc_fraction(chain: WhiskerChain) -> np.ndarray:
    """[N−1] s/S of the bending joints (nodes 1..N−1; nodes are equidistant along the arc)."""
    return np.arange(1, chain.links) / chain.links


def link_arc_fraction(chain: WhiskerChain) -> np.ndarray:
    """[N] s/S of the link mid-points."""
    return (np.arange(chain.links) + 0.5) / chain.links


def profile(gamma: float, fraction: np.ndarray) -> np.ndarray:
    """exp(γ·(fraction − ½))."""
    return np.exp(gamma * (fraction - 0.5))
