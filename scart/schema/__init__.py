"""The XML Schema of the ``urn:scart:1.0`` dialect (``scart-1.0.xsd``), shipped as package data."""
