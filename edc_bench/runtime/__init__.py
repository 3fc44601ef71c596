"""The bench loop and what it needs at run time: clocks, deadlines, the bus, trace buffers.

The one place where time, I/O and the controller's math meet.
"""
