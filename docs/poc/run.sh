#!/bin/sh
# The proof of concept (thesis chapter 6, Table 6.1) as committed in docs/poc.
# About 30 minutes on 2 cores: the search 18 min, the thesis policy 3 min, each
# closed-loop table 1-2 min.
set -e
# table FILE TITLE COMMAND...: the command's table under a title that names the command.
table() {
    file=$1; title=$2; shift 2
    { printf '# %s\n\nWritten by `%s` (`docs/poc/run.sh`).\n\n' "$title" "$*"; "$@"; } > "$file"
}
# Policy search on the red cup alone, 20 particles into the standard bowl (packaged as
# agents/thesis/poc_search_red_cup_20.json, the closed-loop policy's default parameters).
pour-gym search --objects red_cup --target-objects standard_bowl --objective error \
    --target-amount 20 --generations 10 --population 8 --episodes 6 --seed 1 --out docs/poc
cp docs/poc/search.json agents/thesis/poc_search_red_cup_20.json
# The thesis's open-loop policy: 60 red-cup samples, then the seven cups, 3 pours each.
table docs/poc/poc_thesis_20.md "Proof of concept: the thesis's open-loop policy, 20 particles" \
    pour-gym poc --policy thesis --samples 60 --episodes 3 --seed 100 --out docs/poc
# The closed-loop policy at 20 particles (2.5 ml), 10 ml and 25 ml (seeds the search
# never saw: it used 1000-1005).
table docs/poc/poc_closed-loop_20.md "Proof of concept: the closed-loop policy, 20 particles" \
    pour-gym poc --policy closed-loop --episodes 3 --seed 100 --out docs/poc
table docs/poc/poc_closed-loop_80.md \
    "Proof of concept: the closed-loop policy, 80 particles (10 ml)" \
    pour-gym poc --policy closed-loop --episodes 3 --seed 100 --target-ml 10 --out docs/poc
table docs/poc/poc_closed-loop_200.md \
    "Proof of concept: the closed-loop policy, 200 particles (25 ml)" \
    pour-gym poc --policy closed-loop --episodes 3 --seed 100 --target-ml 25 --out docs/poc
