"""feedlog.train"""
