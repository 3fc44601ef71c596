"""The simulated rig: plant, valve wear, sensors, firmware over them, runners."""
