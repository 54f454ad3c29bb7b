"""Several whiskers' forward kinematics at once (pipeline.model.joints.bent_chains) against one
whisker's (bent_chain): the same frames and nodes to the bit, so the start check that uses it
(pipeline.engines.common.blocked_at_start) decides as before."""

import numpy as np

from pipeline.config.physics import MaterialConfig
from pipeline.model.array import build_array
from pipeline.model.joints import bent_chain, bent_chains
from pipeline.model.morphology import model_rat


def test_bent_chains_are_each_whiskers_bent_chain_to_the_bit():
    array = build_array(model_rat().select("RA0,RA3,RB1,RC2,RD4,RE1,LC1"), MaterialConfig())
    rng = np.random.default_rng(3)
    physics = [w.physics for w in array.whiskers]
    q = [rng.normal(0.0, 0.05, len(p.layout.labels)) for p in physics]
    frames, nodes = bent_chains(physics, q)
    assert frames.shape[0] == nodes.shape[0] == len(physics)
    for k, (p, angles) in enumerate(zip(physics, q)):
        one_frames, one_nodes = bent_chain(p, angles)
        assert np.array_equal(frames[k], one_frames[0])
        assert np.array_equal(nodes[k], one_nodes[0])
    assert not np.array_equal(nodes[0], nodes[1])          # each row is its own whisker's chain
