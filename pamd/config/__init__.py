"""Rig configuration: YAML validated in one place into typed objects."""

from pamd.config.loader import LoadedConfig, builtin_config_path, load_config, load_config_text
from pamd.config.schema import RigConfig

__all__ = ["LoadedConfig", "RigConfig", "builtin_config_path", "load_config", "load_config_text"]
