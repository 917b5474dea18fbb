"""Agents of pour-gym, installed as ``pour_gym.agents``, grouped by kind.

- :mod:`~pour_gym.agents.policies`: one episode of a policy (``rollout``), the scripted
  expert, a residual on it, CMA-ES policy search.
- :mod:`~pour_gym.agents.training`: SB3 training behind ``train.py`` (recipes, runs,
  curves, the native vector env for SB3, curricula, demonstrations and their Minari
  datasets, sweeps, RLlib); trained models that ship with pour-gym live in
  ``models/<name>/``.
- :mod:`~pour_gym.agents.evaluation`: success, amount error and spill per container,
  aggregates and intervals over seeds, the baselines, generalisation and family reports.
- :mod:`~pour_gym.agents.thesis`: the thesis's experiments 1 and 2 and its proof of
  concept (Table 6.1).
- :mod:`~pour_gym.agents.cluster`: running any of them on Ray.
"""
