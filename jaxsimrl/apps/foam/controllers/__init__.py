"""Controllers shipped with the package: ``default/`` is the one ``jaxsimrl solve`` uses without --policy.

A controller is files only, a minimal train-foam run directory: ``config.json``, one checkpoint under
``checkpoints/<update>/``, ``provenance.json`` (the run, the checkpoint and the training family it came
from) and ``acting.npz`` (the checkpoint's acting arrays, jaxsimrl.policy.arrays; optional: without it,
or when it does not match the checkpoint, the checkpoint is restored). Replacing those files replaces
the default; no code names a run.
"""
