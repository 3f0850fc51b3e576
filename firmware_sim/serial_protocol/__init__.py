"""Device side of the DigiForce serial protocol (docs/serial-protocol.md): framing, command set, transports."""
