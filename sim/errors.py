"""Exception types shared by every dexaug package.

Each error message names the file or field at fault and what was expected, so a user can fix
the input without reading the code.
"""


class DexaugError(Exception):
    """Base class: every error dexaug raises on purpose derives from it (the CLI prints these
    as one line instead of a traceback)."""


class AssetError(DexaugError):
    """An asset root, robot model or object file is missing or cannot be loaded."""


class ConfigError(DexaugError):
    """A TOML config is missing a key, has a value of the wrong type or range, or does not
    match the model it describes."""


class GraspInputError(DexaugError):
    """A grasp given to the validator has the wrong shape or non-finite values."""


class UsageError(DexaugError):
    """A command line asks for something argparse cannot refuse alone: a combination of
    options, or an input with nothing in it for the command to do."""


class NetworkError(DexaugError):
    """A port cannot be listened on (taken by another process, not allowed) or a network
    service cannot start."""
