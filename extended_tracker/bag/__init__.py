"""Bag reading and writing (rosbags) and the offline replay."""
