"""pamd.loop.control"""
