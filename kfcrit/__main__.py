"""``python -m kfcrit`` runs the command line."""
from kfcrit.cli.main import main

if __name__ == "__main__":
    main()
