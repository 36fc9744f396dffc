"""Interaction service: contacts -> impacts -> mapping -> sound, graphics, registered messages."""
