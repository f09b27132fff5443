"""Driving the layer over many recordings at once, within a memory budget."""
