"""The pump's physics: variant -> plant parameters -> feedforward parameters, and wear.

Pure: what the controller assumes and what the simulator simulates both come
from here, so neither takes its model from the other.
"""
