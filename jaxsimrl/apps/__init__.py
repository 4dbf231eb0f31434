"""The applications built on the core, one subpackage each (found through jaxsimrl.plugin): ``foam``,
OpenFOAM's simpleFoam under a relaxation controller."""
