"""The science: numpy, scipy and OpenCV only (checked by import-linter)."""
