"""``python -m treeform`` runs the command line (same as the ``treeform`` script)."""

from treeform.cli.app import main

if __name__ == "__main__":
    main()
