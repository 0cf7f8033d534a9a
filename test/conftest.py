"""Test-wide settings: DDS stays on this machine, each run on its own domain."""
import os
import random

# Network rule: never let DDS discovery leave the machine, and keep test runs apart.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random(os.getpid()).randint(100, 200)))
