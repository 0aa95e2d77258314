"""feedlog.toolpath"""
