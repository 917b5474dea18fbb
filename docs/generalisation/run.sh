#!/bin/sh
# The generalisation study: PPO trained on the red cup alone, with the warped features
# or with raw state, evaluated on the thesis's nine objects and the pybullet mug.
# Run from the repository root after `make demo`; about an hour on a 2-core machine.
set -e
PY=${PY:-.venv/bin/python}
for ENV in ParticleDrop TiltPour; do
  for MODE in features state; do
    $PY train.py --env PourGym/$ENV-v0 --algo ppo --objects train --obs-mode $MODE \
      --timesteps 20000 --seed 0 --eval-objects all,pybullet_mug --eval-episodes 100 \
      --out runs/study/${ENV}_${MODE}
  done
done
# The head camera (docs/sensors.md): depth with the CNN recipe, points with the default.
for SEED in 0 1 2; do
  SUFFIX=$([ $SEED = 0 ] && echo "" || echo "_s$SEED")
  $PY train.py --env PourGym/TiltPour-v0 --algo ppo --recipe camera --objects train \
    --obs-mode depth --timesteps 20000 --seed $SEED --eval-objects all,pybullet_mug \
    --eval-episodes 100 --out runs/study/TiltPour_depth$SUFFIX
  $PY train.py --env PourGym/TiltPour-v0 --algo ppo --objects train --obs-mode points \
    --timesteps 20000 --seed $SEED --eval-objects all,pybullet_mug --eval-episodes 100 \
    --out runs/study/TiltPour_points$SUFFIX
done
$PY -m pour_gym.apps.cli report generalisation --runs runs/study --out docs/generalisation
