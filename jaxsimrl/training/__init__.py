"""Training runs as library calls: what a ``jaxsimrl train-*`` command does once its input is checked.

:mod:`jaxsimrl.training.lorenz` runs train-lorenz (an application runs its own training, e.g.
train-foam's PPO on real simpleFoam cases); :mod:`jaxsimrl.training.common` is what they share (config.json's
record, the restore from a checkpoint, the one-line errors of input a run cannot start with). The command-line
modules (:mod:`jaxsimrl.cli`) parse and validate, call these, and print.
"""
