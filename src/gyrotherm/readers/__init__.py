"""Readers of the user's own data (PX4 ULog, ArduPilot DataFlash, rosbag2/MCAP)."""
