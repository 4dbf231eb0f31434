#!/bin/sh
# A controller on many cases (issue 35), seventh try: family-v6 (the SIMPLEC box, lr 1e-3) with share 0.5 at
# the training family's best constant for the case's algorithm, clipped into its box (FAMILY_CONSTANT and
# around_own in jaxsimrl/apps/foam/solve/settings.py; experiments/controller/family-constant/): plain SIMPLE
# (0.8, 0.3, 0.9), 0.64-0.77x its training variants' own iterations, where family-v6 started at the own
# settings and had moved them by little in 24 updates; SIMPLEC (0.95, 1.0, 0.95) as in family-v6.
# Families: family-v3-setup/run.sh (runs/family-full, runs/family-val-full).
jaxsimrl train-foam --family runs/family-full --config experiments/controller/family-v7-setup/train-config.json \
    --residual-features 2 --observe-progress --observe-action --pool 2 --num-envs 4 --init-action 0.5 0.5 0.5 \
    --episodes 3000 --seed 0 --out experiments/controller/family-v7
python experiments/controller/family-v1-setup/validate.py experiments/controller/family-v7 runs/family-val-full \
    --out experiments/controller/family-v7-setup/validation.jsonl
