"""The `cosim` command line (typer): one module per group of subcommands; `cosim.cli.app:main` is the entry point.
"""
