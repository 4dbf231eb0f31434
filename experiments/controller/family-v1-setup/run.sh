#!/bin/sh
# The first controller trained on many cases (issue 35): 15 coarse variants of four training bases.
# Build the family (seeded; T3A-2 is dropped after: its own settings do not converge in its 1000 iterations):
T=/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam
jaxsimrl family $T/pitzDaily $T/pitzDailyExptInlet $T/T3A --out runs/family-train --variants 4 --seed 0 \
    --speed 0.7 1.5 --viscosity 0.7 1.5 --mesh 0.5 0.5
jaxsimrl family $T/airFoil2D --out runs/family-train --variants 4 --seed 1 --speed 0.7 1.5 --viscosity 0.7 1.5 \
    --angle -4 4
rm -rf runs/family-train/T3A-2
# Train (resume with: jaxsimrl train-foam --resume experiments/controller/family-v1):
jaxsimrl train-foam --family runs/family-train --config experiments/controller/family-v1-setup/train-config.json \
    --residual-features 2 --observe-progress --observe-action --pool 2 --num-envs 4 --init-action 0.8 0.8 0.8 \
    --episodes 3000 --seed 0 --out experiments/controller/family-v1
# The validation family (checkpoints are chosen on it; training bases only, other seeds):
jaxsimrl family $T/pitzDaily $T/pitzDailyExptInlet $T/T3A --out runs/family-val --variants 1 --seed 5 \
    --speed 0.7 1.5 --viscosity 0.7 1.5 --mesh 0.5 0.5
jaxsimrl family $T/airFoil2D --out runs/family-val --variants 1 --seed 6 --speed 0.7 1.5 --viscosity 0.7 1.5 \
    --angle -4 4
python experiments/controller/family-v1-setup/validate.py experiments/controller/family-v1 runs/family-val \
    --out experiments/controller/family-v1-setup/validation.jsonl
