"""Planning: a general iLQR/DDP solver, composable dynamics, the kinematic gaze-chain body."""
