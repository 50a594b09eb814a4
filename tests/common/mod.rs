pub mod withheld;
