// Tests to come (issues 3 and 6).
