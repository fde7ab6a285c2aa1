"""Shipped YAML configs and suites, installed as ``assocbench.configs``."""
