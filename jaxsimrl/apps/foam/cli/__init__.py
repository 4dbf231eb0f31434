"""jaxsimrl.apps.foam.cli."""
