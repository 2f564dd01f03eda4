"""pamd.control"""
