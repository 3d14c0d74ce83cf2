"""Bridge between the SMM ROS interfaces and the hydraulic test bench."""
