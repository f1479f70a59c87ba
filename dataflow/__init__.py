"""dataflow: Orocos RTT-style data-flow components for Python."""
