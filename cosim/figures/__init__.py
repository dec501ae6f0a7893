"""Paper-style figures of runs (matplotlib), comparisons of several runs, sweep histograms.
"""
