"""A horse's page: its indicators' trends against its own normal band, and its page as a share link shows it."""
