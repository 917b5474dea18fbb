"""Agents of pour-gym, installed as ``pour_gym.agents``.

- :mod:`~pour_gym.agents.rollout`: one episode of a policy (the loop everything uses).
- :mod:`~pour_gym.agents.scripted`: a pouring policy that reads only the warped features.
- :mod:`~pour_gym.agents.experiments`: the thesis's experiments 1 and 2 with ROC curves.
- :mod:`~pour_gym.agents.poc`: the thesis's proof of concept (Table 6.1).
- :mod:`~pour_gym.agents.training`: SB3 training behind ``train.py``; trained models that
  ship with pour-gym live in ``models/<name>/``.
- :mod:`~pour_gym.agents.curriculum`: training episodes that start part of the way.
- :mod:`~pour_gym.agents.evaluate`: success, amount error and spill per container.
- :mod:`~pour_gym.agents.search`: CMA-ES policy search.
- :mod:`~pour_gym.agents.study`: the generalisation report (features against state).
"""
