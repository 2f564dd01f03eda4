"""pamd.config"""
