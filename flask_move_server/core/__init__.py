"""What every room uses: the Robot facade, its events and happenings, errors, geometry, names, state files."""
