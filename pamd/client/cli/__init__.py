"""pamd.client.cli"""
