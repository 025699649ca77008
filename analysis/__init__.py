"""dfwb: a describing-function workbench for friction and backlash, on FMI co-simulation."""

__version__ = "0.1.0"
