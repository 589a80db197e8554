"""`admmkit bench precision`: work-precision, the true error against time of every rule and the peers."""
