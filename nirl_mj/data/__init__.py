"""The shared vocabulary and the files on disk: phi(s) and the actions, the trajectory record,
the dataset format, outcome rates, the run-directory type, atomic writes. Imports nothing of ours."""
