"""`tactilepipe <stage>`: every pipeline stage, usable with or without Snakemake (entry: cli.main).

One module per study declares its commands, each once, on its function (``registry.command``);
``common`` holds what they share. This file imports nothing, so a stage's code (pipeline.codedeps)
is its own module's imports and never another study's.
"""
