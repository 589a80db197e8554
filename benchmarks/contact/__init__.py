"""Studies of elastic contact: the paper's reproduction and tables, speed, scale, 3D, Hertz, friction, the sparse backends."""
