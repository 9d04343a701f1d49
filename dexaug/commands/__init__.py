"""The ``dexaug`` subcommands, one module per group.

What it holds: :mod:`~dexaug.commands.registry` (the ``@command`` decorator and the parser
built from what it registered); a module per command or group (``generate``, ``augment``, ``batch``,
``validate``, ``diagnose``, ``export``, ``demo``, ``arm``, ``teleop``, ``replay``, ``stream``,
``repair``, ``view``, ``ui``, ``workspace``, ``assets``), each registering its subcommands on
import; and what they share: :mod:`~dexaug.commands.options` (flags that mean the same
everywhere), :mod:`~dexaug.commands.argtypes`, :mod:`~dexaug.commands.guards` (checks before any
work), :mod:`~dexaug.commands.running`, :mod:`~dexaug.commands.network`,
:mod:`~dexaug.commands.workers`.

What to import: nothing here from code outside the CLI — call :func:`dexaug.cli.main`, or the
job a command wraps (its module names it, e.g. ``diagnose_dataset``). A new command is a module
here whose functions carry ``@command``; its heavy imports stay inside the functions, so that
``dexaug --help`` starts fast.
"""
