//! Zones → sparse depth map at camera resolution.
