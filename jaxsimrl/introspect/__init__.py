"""Look inside a trained policy: load it, act with it, roll it out, and the helpers a scientist reaches for.

``load_policy(run_dir)`` (also ``jaxsimrl.load_policy``) gives a :class:`LoadedPolicy`. The helpers
each return plain data (numpy arrays in a NamedTuple) and have a matplotlib ``plot_*`` companion:

- :func:`policy_slice` / :func:`plot_policy_slice`: the action and the value on a 2-D slice of
  observation space (the other components held fixed); :func:`policy_profile` /
  :func:`plot_policy_profile` on a 1-D one (a foam policy's factors against its state);
- :func:`action_sensitivity` / :func:`plot_sensitivity`: d action / d observation along a
  trajectory (``jax.jacobian``), as a heat map over time;
- :func:`hidden_pca` / :func:`plot_hidden_pca`: the LSTM hidden state of a trajectory on its leading
  principal components, coloured by |velocity|, reward or any record key.

An application adds its own (the OpenFOAM one's factor histories: jaxsimrl.apps.foam.introspect).
"""

from jaxsimrl.introspect.hidden import HiddenPCA, hidden_pca, plot_hidden_pca
from jaxsimrl.introspect.loading import LoadedPolicy, load_agents, load_policy
from jaxsimrl.introspect.sensitivity import Sensitivity, action_sensitivity, plot_sensitivity
from jaxsimrl.introspect.slices import (
    PolicyProfile,
    PolicySlice,
    plot_policy_profile,
    plot_policy_slice,
    policy_profile,
    policy_slice,
)
from jaxsimrl.policy.distribution import ActionDistribution

__all__ = ["ActionDistribution", "HiddenPCA", "LoadedPolicy", "PolicyProfile", "PolicySlice", "Sensitivity",
           "action_sensitivity", "hidden_pca", "load_agents", "load_policy", "plot_hidden_pca",
           "plot_policy_profile", "plot_policy_slice", "plot_sensitivity", "policy_profile", "policy_slice"]
