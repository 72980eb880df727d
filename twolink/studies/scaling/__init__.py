"""The N-link scaling study: decentralized and centralized synthesis as links are added.
"""
