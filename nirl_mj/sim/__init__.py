"""The simulation: task specs, arenas, the Robotino and its drive, sensing, the dm_control task, and
the one episode loop. Imports only nirl_mj.data."""
