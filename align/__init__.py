"""feedlog.align"""
