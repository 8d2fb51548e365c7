"""Seeds, run directories, training and evaluation on the simulation, demonstrations, the protocol and
its executors, compare, sweep and the main job."""
