"""Scripted data collection: experiment plans, their dry run, and the sequencer
that runs them inside the loop."""
