"""The process values of the DBC's ``ResultValue`` frame: signal name → the name the host records the value under (a
module of its own, so that the recorder's schemas do not import the CAN stack)."""

PROCESS_VALUES = {"XMax": "x_max", "XMin": "x_min", "YMax": "y_max", "YMin": "y_min", "XAtYMax": "x_at_y_max",
                  "YAtXMax": "y_at_x_max", "XEnd": "x_end", "YEnd": "y_end", "Duration": "duration"}
