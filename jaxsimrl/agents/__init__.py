"""Learning agents (currently: pure-JAX PPO in jaxsimrl.agents.ppo)."""
