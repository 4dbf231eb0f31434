"""The ``jaxsimrl`` command line: one module per group of subcommands, dispatched by :mod:`.main`."""
