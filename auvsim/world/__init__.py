"""What the vehicle moves over: the seafloor and its ray casts."""
