"""Sockets and time: TCP/UDP transport for libfranka clients, the 1 kHz tick, the CLI."""
