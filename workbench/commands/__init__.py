"""Sub-command modules of the ``workbench`` console script.

Each module defines ``register(subparsers)``, which adds its sub-commands to an
``argparse`` sub-parser collection and sets ``func`` (a callable taking the parsed
``argparse.Namespace`` and returning an exit code or ``None``) as default.
"""
