"""Configuration: pydantic models for every config file and the one loader they share.

Precedence, highest first: CLI flag > environment variable > YAML file > model default.
"""

from pipeline.config.loader import ConfigSource, env_overrides, load_config

__all__ = ["ConfigSource", "env_overrides", "load_config"]
