"""Comparisons of the club's rides: horses across gaits and within one, the leaderboard, grades, saddles."""
