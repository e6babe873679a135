"""The ``treeform`` command line (typer); the only place that draws progress bars."""
