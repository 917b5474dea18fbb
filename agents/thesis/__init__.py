"""The thesis's reproductions: its experiments 1 and 2, and its proof of concept.

- :mod:`~pour_gym.agents.thesis.experiments`: experiments 1 and 2 with ROC curves.
- :mod:`~pour_gym.agents.thesis.poc`: the proof-of-concept pouring policy (Table 6.1),
  with its searched parameters (``poc_search_red_cup_20.json``).
"""
