#!/bin/sh
# The proof of concept (thesis chapter 6, Table 6.1) as committed in docs/poc.
# About 30 minutes on 2 cores: the search 18 min, the thesis policy 3 min, each
# closed-loop table 1-2 min.
set -e
# Policy search on the red cup alone, 20 particles into the standard bowl (packaged as
# agents/poc_search_red_cup_20.json, the closed-loop policy's default parameters).
pour-gym search --objects red_cup --target-objects standard_bowl --objective error \
    --target-amount 20 --generations 10 --population 8 --episodes 6 --seed 1 --out docs/poc
cp docs/poc/search.json agents/poc_search_red_cup_20.json
# The thesis's open-loop policy: 60 red-cup samples, then the seven cups, 3 pours each.
pour-gym poc --policy thesis --samples 60 --episodes 3 --seed 100 --out docs/poc \
    > docs/poc/poc_thesis_20.md
# The closed-loop policy at 20 particles (2.5 ml), 10 ml and 25 ml (seeds the search
# never saw: it used 1000-1005).
pour-gym poc --policy closed-loop --episodes 3 --seed 100 --out docs/poc \
    > docs/poc/poc_closed-loop_20.md
pour-gym poc --policy closed-loop --episodes 3 --seed 100 --target-ml 10 --out docs/poc \
    > docs/poc/poc_closed-loop_80.md
pour-gym poc --policy closed-loop --episodes 3 --seed 100 --target-ml 25 --out docs/poc \
    > docs/poc/poc_closed-loop_200.md
