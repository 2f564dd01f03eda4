"""pamd.sim"""
