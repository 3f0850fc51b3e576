"""Host-side drivers: talk to the (real or simulated) hardware over CAN and serial only."""
