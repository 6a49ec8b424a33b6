"""Which rides move most alike: the comparisons of result documents and files, the club's lists and jobs."""
