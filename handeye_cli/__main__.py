"""``python -m handeye_cli`` runs the ``handeye`` command."""
from .cli import main

main()
