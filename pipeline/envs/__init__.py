"""Gymnasium environments: ``import pipeline.envs`` registers ``whisker_pipeline/Whisking-v0``
(:mod:`pipeline.envs.whisking`, docs/closed_loop.md)."""

from gymnasium.envs.registration import register, registry

ENV_ID = "whisker_pipeline/Whisking-v0"

if ENV_ID not in registry:
    register(id=ENV_ID, entry_point="pipeline.envs.whisking:WhiskingEnv", max_episode_steps=500)
