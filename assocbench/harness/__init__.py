"""The harness: configs, runs, sweeps, leaderboards and the CI accuracy check."""
