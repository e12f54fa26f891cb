"""Models: contact mechanics, mixed-dimensional flow, poromechanics and their time loop."""
