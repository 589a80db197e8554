"""Studies of the framework itself: the loop's overhead, four problems from the building blocks, the executors."""
