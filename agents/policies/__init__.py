"""Policies: one episode of a policy, the scripted expert, a residual on it, CMA-ES search.

- :mod:`~pour_gym.agents.policies.rollout`: one episode of a policy (the loop everything
  uses).
- :mod:`~pour_gym.agents.policies.scripted`: a pouring policy that reads only the warped
  features.
- :mod:`~pour_gym.agents.policies.residual`: a learned correction added to the scripted
  policy's action.
- :mod:`~pour_gym.agents.policies.search`: CMA-ES search over the scripted policy's
  parameters.
"""
