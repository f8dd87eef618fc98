"""Data model: rotations (the one place that knows quaternion conventions), skeleton clips, forward kinematics, rig binding."""
