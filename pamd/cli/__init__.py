"""pamd.cli"""
