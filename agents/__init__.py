"""Agents of pour-gym, installed as ``pour_gym.agents``: the thesis's classifiers and
pouring policy, SB3 training helpers and policy search, as the environments arrive."""
