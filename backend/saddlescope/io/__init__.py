"""Files, no web or DB: video frames, ride bundles, C3D/TRC, exports."""
