"""Count frames of the intelligent sensors: text frame logs and recorded CAN traffic → the frame table."""
