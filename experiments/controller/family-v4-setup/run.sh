#!/bin/sh
# A controller on many cases (issue 35), fourth try: family-v3 with the factors frozen within a decade of
# each case's criterion (FoamEnvConfig.freeze_decades; family-v3-setup/jitter-freeze.json shows that
# this keeps airFoil2D converging under factors that change every 50 iterations). The training and
# validation families are family-v3's (built by family-v3-setup/run.sh into runs/family-full and
# runs/family-val-full).
# Train (resume with: jaxsimrl train-foam --resume experiments/controller/family-v4):
jaxsimrl train-foam --family runs/family-full --config experiments/controller/family-v4-setup/train-config.json \
    --residual-features 2 --observe-progress --observe-action --pool 2 --num-envs 4 --init-action 0.5 0.5 0.5 \
    --episodes 3000 --seed 0 --out experiments/controller/family-v4
# Choose checkpoints on the validation family:
python experiments/controller/family-v1-setup/validate.py experiments/controller/family-v4 runs/family-val-full \
    --out experiments/controller/family-v4-setup/validation.jsonl
