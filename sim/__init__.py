"""feedlog.sim"""
