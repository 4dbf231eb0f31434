"""A trained foam policy's rollouts (real simpleFoam episodes) and factor histories:
:func:`factor_history` / :func:`plot_factor_history`: alpha_u and alpha_p against the SIMPLE iteration
and against the residual they answered, per inlet velocity."""

from jaxsimrl.apps.foam.introspect.factors import FactorHistory, factor_history, plot_factor_history

__all__ = ["FactorHistory", "factor_history", "plot_factor_history"]
