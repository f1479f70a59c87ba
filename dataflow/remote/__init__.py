"""Remote access to data-flow components over gRPC (the JOrocos mirror)."""
