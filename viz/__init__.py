"""feedlog.viz"""
