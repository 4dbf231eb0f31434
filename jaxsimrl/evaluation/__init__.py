"""Evaluation of trained agents: rollouts against baselines, reports and figures."""
