"""Agents of pour-gym, installed as ``pour_gym.agents``.

The thesis's classifiers and pouring policy, SB3 training helpers and policy search live
here as the environments arrive.
"""
