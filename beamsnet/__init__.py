"""beamsnet: BeamsNetV1/V2 trainers and baselines on auvsim datasets (to come)."""
