"""Sub-command modules of the ``workbench`` console script.

Each module defines ``register(subparsers)``: it receives an ``argparse``
sub-parser collection (a group's, or the top level's for ``view`` and
``demo``), adds its commands to it with
:func:`workbench.commands.common.add_command` and sets each command's ``func``
(a callable taking the parsed ``argparse.Namespace`` and returning an exit code
or ``None``). :data:`workbench.cli.GROUPS` lists which modules fill which group.
Helpers the commands share (reading models and arrays, checking output names,
parsing vectors, writing summaries) live in :mod:`workbench.commands.common`.
"""
