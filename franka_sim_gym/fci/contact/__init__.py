"""What the robot senses of contact: estimate.py (the external-torque estimate and the
wrench at K), collision.py (SetCollisionBehavior's thresholds), sensing.py (the
RobotState's contact group every cycle and the collision reflexes 6 and 7), and their
one text, fci/contact/_contact.c.
"""
