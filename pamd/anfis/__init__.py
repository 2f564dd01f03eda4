"""pamd.anfis"""
