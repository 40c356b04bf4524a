"""The Zenoh bus: sessions, key names, typed messages and their codec."""
