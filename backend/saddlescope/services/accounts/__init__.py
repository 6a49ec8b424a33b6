"""Clubs, users and what they may do: sign-in, permissions, its guard under abuse, share links."""
