"""``zarco campaign``: randomised campaigns of simulated missions, judged against
their targets (spec, draw, run, results, tables, plots, compare, cli)."""
