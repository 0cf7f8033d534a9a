"""Device state objects: decoded readings in, BatteryState/diagnostic reports out."""
