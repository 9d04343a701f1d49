"""The ``dexaug`` subcommands, one module per group; importing a module registers its commands
in :mod:`dexaug.commands.registry`."""
