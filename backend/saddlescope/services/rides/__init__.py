"""Rides: registered from a bundle or clips, what makes one complete, and its derived status."""
