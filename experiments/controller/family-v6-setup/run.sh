#!/bin/sh
# A controller on many cases (issue 35), sixth try: family-v5 with the SIMPLEC box of around_own
# (jaxsimrl/apps/foam/solve/settings.py): alpha_u never below the case's own (family-v5-setup/t3a_floor.json)
# and share 0.5 at the box top (0.95, 1.0, 0.95), where the residual rule starts a SIMPLEC case
# (simplec_top.json: 0.68-0.73x own on T3A-0 and pitzDaily-0); plain SIMPLE as before (pivot at its own).
# lr 1e-3 (family-v5's 2.5e-4 had moved nothing in 21 updates).
# Families: family-v3-setup/run.sh (runs/family-full, runs/family-val-full).
jaxsimrl train-foam --family runs/family-full --config experiments/controller/family-v6-setup/train-config.json \
    --residual-features 2 --observe-progress --observe-action --pool 2 --num-envs 4 --init-action 0.5 0.5 0.5 \
    --episodes 3000 --seed 0 --out experiments/controller/family-v6
python experiments/controller/family-v1-setup/validate.py experiments/controller/family-v6 runs/family-val-full \
    --out experiments/controller/family-v6-setup/validation.jsonl
