"""The paper (Machmudah & Parman 2013): its published numbers, the reconstruction of its
obstacle layouts from them, and the report that reproduces its tables and figures.
"""
