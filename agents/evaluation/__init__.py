"""Evaluation and studies: scores per container, aggregates over seeds, the reports.

- :mod:`~pour_gym.agents.evaluation.evaluate`: success, amount error and spill per
  container.
- :mod:`~pour_gym.agents.evaluation.aggregate`: rliable's aggregates and every interval
  the project reports.
- :mod:`~pour_gym.agents.evaluation.baselines`: the baselines report over training runs.
- :mod:`~pour_gym.agents.evaluation.generalisation`: the generalisation report (features
  against state on unseen containers).
- :mod:`~pour_gym.agents.evaluation.family`: the procedural family study.
"""
