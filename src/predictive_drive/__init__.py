"""predictive_drive: model predictive torque control of electric drives on a ROS 2 graph.

``core`` is the ROS-free library (machines, inverter, control laws, metrics); ``interface`` owns the
topic table and message encodings; ``bag`` reads and writes rosbag2-style MCAP; ``ros`` holds the
nodes; ``api`` and ``cli`` are the command line.
"""

__all__ = ["__version__"]

__version__ = "0.1.0"
