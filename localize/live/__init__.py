"""The live loop, free of any middleware: the newest frame, odometry sync, the MAVLink sender."""
