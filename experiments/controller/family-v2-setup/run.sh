#!/bin/sh
# A controller on many cases (issue 35), second try: full-mesh variants of four training tutorials, acting
# around each case's own factors (share 0.5 = the case's own; family-v1, on mesh-0.5 variants, found no
# room above the own settings of the SIMPLEC cases there: experiments/README.md).
T=/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam
jaxsimrl family $T/pitzDaily $T/pitzDailyExptInlet $T/T3A --out runs/family-full --variants 4 --seed 0 \
    --speed 0.7 1.5 --viscosity 0.7 1.5
jaxsimrl family $T/airFoil2D --out runs/family-full --variants 4 --seed 1 --speed 0.7 1.5 --viscosity 0.7 1.5 \
    --angle -4 4
# Train (resume with: jaxsimrl train-foam --resume experiments/controller/family-v2):
jaxsimrl train-foam --family runs/family-full --config experiments/controller/family-v2-setup/train-config.json \
    --residual-features 2 --observe-progress --observe-action --pool 2 --num-envs 4 --init-action 0.5 0.5 0.5 \
    --episodes 3000 --seed 0 --out experiments/controller/family-v2
# The validation family (checkpoints are chosen on it; training bases only, other seeds):
jaxsimrl family $T/pitzDaily $T/pitzDailyExptInlet $T/T3A --out runs/family-val-full --variants 1 --seed 5 \
    --speed 0.7 1.5 --viscosity 0.7 1.5
jaxsimrl family $T/airFoil2D --out runs/family-val-full --variants 1 --seed 6 --speed 0.7 1.5 \
    --viscosity 0.7 1.5 --angle -4 4
python experiments/controller/family-v1-setup/validate.py experiments/controller/family-v2 runs/family-val-full \
    --out experiments/controller/family-v2-setup/validation.jsonl
