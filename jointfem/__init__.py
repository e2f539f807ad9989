"""jointfem"""
