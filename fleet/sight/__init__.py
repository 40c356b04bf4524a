"""The line's sight: what perception (`perception/`) makes of a line's cameras, for the processes of a running line
and the env alike. The surfaces parts lie on, the line's parts bound to the cameras' tracks (`LineSight`), one
camera frame seen (`Seer`), which frame a node may act on, and the parts carried to the tick it acts at."""
