"""MuJoCo side of dexaug: assets, hand models, scenes, contacts, rendering and grasp validation.

Everything here works on plain arrays and MuJoCo models; nothing prints (the CLI reports).
"""
