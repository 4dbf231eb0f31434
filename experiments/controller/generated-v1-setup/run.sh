#!/bin/sh
# A recurrent controller on generated cases (issue 47), first recipe. Run from the repository root.
# The cases (foam_bridge's generator; own runs paid once, by the generator, on its workers):
#   training:   the 200 specs of seed 0, plain SIMPLE cases at resolution 0.7 (the smallest whose settings'
#               ranking agrees with the full size's), SIMPLEC cases at full size (no coarse resolution
#               agrees for them): experiments/controller/generated-ranking/
#   validation: 12 full-size cases of seed 1 (checkpoints and seeds are chosen on these only)
jaxsimrl generate-cases runs/generated-train-r0.7 -n 200 --seed 0 --resolution 0.7 --workers 2
jaxsimrl generate-cases runs/generated-train-r1 -n 200 --seed 0 --resolution 1.0 --workers 2
jaxsimrl generate-cases runs/generated-val -n 12 --seed 1 --resolution 1.0 --workers 2
# Train: an LSTM (2 x 64 tanh, LSTM 64) that observes the residuals at the last two step boundaries,
# progress, the algorithm, the factors in force and the last step's gain; it acts every 25 iterations in
# shares of each case's box, share 0.5 being the case's own factors (pivot_at "own", init-action 0.5: the
# initial policy is the user's own run); the reward is the solver's CPU seconds, per case in units of its
# own run's (100 = as costly as its own settings). Resume with: jaxsimrl train-foam --resume RUN.
# RECIPE=v2: wider exploration (train-config-v2.json: init_log_std -1.0, ent_coef 0.005) on the
# deterministic part of the cost, the SIMPLE iterations (per case in units of its own run's).
SEED=${SEED:-0}
RECIPE=${RECIPE:-v1}
CONFIG=experiments/controller/generated-v1-setup/train-config.json
REWARD=solver-time
# RECIPE=v3: v2 with every factor moving alike both ways from own (train-config-v3.json: action_radius
# 0.15, share s sets own + (2s - 1) x 0.15 in the box).
if [ "$RECIPE" != v1 ]; then
    CONFIG=experiments/controller/generated-v1-setup/train-config-$RECIPE.json
    REWARD=iterations
fi
RUN=experiments/controller/generated-$RECIPE-s$SEED
jaxsimrl train-foam --family $(python experiments/controller/generated-v1-setup/family.py \
        runs/generated-train-r0.7 runs/generated-train-r1) --config $CONFIG \
    --residual-features 2 --observe-progress --observe-action --observe-gain --reward $REWARD \
    --pool 2 --num-envs 4 --steps-per-update 256 --init-action 0.5 0.5 0.5 --episodes 20000 --seed $SEED \
    --out $RUN &
sh experiments/controller/generated-v1-setup/pin.sh $RUN runs/generated-$RECIPE-s$SEED-pinned 4 &
wait
# Validation of the pinned checkpoints (on the full-size validation cases, beside own and the bandit):
#   python experiments/controller/generated-v1-setup/validate.py runs/generated-v1-s0-pinned/uN runs/generated-val \
#       --out experiments/controller/generated-v1-setup/validation-s0.jsonl --updates N
