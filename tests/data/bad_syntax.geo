// A deliberate syntax error: gmsh must report it and hbcontact must show gmsh's message.
Point(1) = {0, 0, 0, 0.1};
Point(2) = {1, 0, 0, 0.1}
Line(1) = {1, 2;
