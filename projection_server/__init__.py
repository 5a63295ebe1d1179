"""projection_server: a ROS 2 Prolog query service with simulation-based temporal projection."""
