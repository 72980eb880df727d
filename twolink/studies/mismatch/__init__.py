"""The model-mismatch study: the gap between the learning model (11) and MuJoCo's full
dynamics, measured, then reported.
"""
