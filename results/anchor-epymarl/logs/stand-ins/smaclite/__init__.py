"""Stand-in: the LBF anchor runs no SMAClite map."""
