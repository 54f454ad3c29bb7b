"""A whisker's frame and rest shape at many protraction angles at once equal them one angle at a
time, bit for bit (the pose sampler's envelopes rely on it: pipeline/scenes/poses.py)."""

import numpy as np

from pipeline.config.physics import ModelConfig
from pipeline.model.array import build_array
from pipeline.model.morphology import model_rat


def test_batched_angles_equal_single_angles_bit_for_bit():
    array = build_array(model_rat().select("RA0,RC3,LE6"), ModelConfig().material)
    thetas = np.concatenate([np.linspace(-0.4, 0.9, 24), np.random.default_rng(3).uniform(-0.5, 1.0, 40)])
    for whisker in array.whiskers:
        frames, nodes = whisker.frame(thetas), whisker.rest_nodes_head(thetas)
        assert frames.shape == (len(thetas), 3, 3) and nodes.shape == (len(thetas),) + whisker.chain.nodes_m.shape
        assert np.array_equal(frames, np.array([whisker.frame(float(t)) for t in thetas]))
        assert np.array_equal(nodes, np.array([whisker.rest_nodes_head(float(t)) for t in thetas]))
        assert np.array_equal(whisker.rest_nodes_head(), whisker.rest_nodes_head(0.0))
        assert np.array_equal(whisker.rest_nodes_head(thetas.reshape(8, 8)), nodes.reshape(8, 8, *nodes.shape[1:]))
