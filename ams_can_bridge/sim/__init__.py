"""Device simulators (pure models) and the runner that puts them on a python-can bus."""
