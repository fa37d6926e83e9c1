"""Gateways between CAN lines and host protocols (CiA 309-3 ASCII, the seed 001 remote-access protocol, MQTT)."""
