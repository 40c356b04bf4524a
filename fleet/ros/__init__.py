"""ROS 2 front ends of a running line: what ROS tools see (topics, services, actions under one name scheme) and
the rosbridge v2 server that serves them over WebSocket. They translate; the sim, trackers and coordinator stay
as they are."""
