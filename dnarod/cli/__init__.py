"""The command line, ``dnarod COMMAND``: one module per command group, each a thin shell over one API call."""
