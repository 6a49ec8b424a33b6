"""Camera rigs: calibrated once (board walk or wand), their clips checked before a ride, the board to print."""
