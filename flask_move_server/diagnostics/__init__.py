"""The first-boot doctor: what owners get wrong on a new robot, checked and said in one report."""
