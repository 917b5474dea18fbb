"""Packaged asset data (installed as ``pour_gym.asset_files``); see ``pour_gym.assets``."""
