"""TODO: docstring"""
