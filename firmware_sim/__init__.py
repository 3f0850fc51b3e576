"""Simulated devices: transducers, the DigiForce-style acquisition unit and their bus endpoints."""
