"""scart: an SCA runtime for Python, bridged to an Orocos-style data-flow world."""
