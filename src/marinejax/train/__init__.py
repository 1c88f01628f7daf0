"""PPO training of marinejax tasks (Brax PPO), with tuned hyperparameters per task."""
