"""The rclpy layer: node, parameter declaration and message conversion."""
