"""Training the networks: the loop, checkpoints and runs of many seeds."""
