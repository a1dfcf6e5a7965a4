"""The realistic scenario's experiments: the line as drawn, the pantograph pair, passes on a
learned map, and their figures."""
