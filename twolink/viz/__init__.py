"""Presentation: headless rendering, videos, plots and number formatting.
"""
