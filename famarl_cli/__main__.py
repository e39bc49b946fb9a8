"""``python -m famarl_cli``: the famarl command line."""

from famarl_cli.cli import main

main()
