"""The shared vocabulary and the files on disk: phi(s) and the actions, the trajectory record, the dataset and run-directory formats, atomic writes. Imports nothing of ours."""
