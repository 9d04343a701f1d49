"""The reference paper's augmenter: object clouds, contact faces, AutoWS workspace clouds, FSG
sampling and the grasp dataset. Pure NumPy/SciPy on arrays; MuJoCo only for hand kinematics."""
