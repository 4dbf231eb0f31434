"""jaxsimrl.apps.foam.evaluation."""
