"""The simulated FCI controller: wire layouts, robot rules, the cycle."""
