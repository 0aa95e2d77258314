"""feedlog.ingest"""
