"""Supervision: the vessel's mode, commands and failsafes."""
